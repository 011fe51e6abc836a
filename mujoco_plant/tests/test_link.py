"""The lockstep link emulation (`--delay`) against its definition: the answer to state k,
sent at t_k = k h, arrives 2 delay later and is in force from the first period starting then;
the newest arrived answer at most --max-age periods old; 0 N m before the first. The expected
schedule below is computed from that definition with integers (k + 2 delay / h periods), not
by the code under test."""

import types

import pytest

pytest.importorskip("mujoco")

from tilting_mujoco import node  # noqa: E402


def link(delay, max_age, period=1e-3):
    a = types.SimpleNamespace(delay=delay, max_age=max_age, period=period)
    n = types.SimpleNamespace(a=a, flight=[], link_tau=0.0, c=dict(torques_applied=0, torques_late=0), age=node.Window())
    return n


def test_a_50_ms_round_trip_applies_the_answer_50_periods_later():
    n = link(0.025, 100)
    # The answer to state k is the number k + 1000 (distinct from the 0 N m before any).
    applied = [node.Node.through_link(n, k, k + 1000.0) for k in range(300)]
    # 0.05 s / 1 ms = 50 periods exactly; floating point must not push it to 51.
    assert applied == [0.0] * 50 + [k - 50 + 1000.0 for k in range(50, 300)]
    assert n.c["torques_applied"] == 250 and n.c["torques_late"] == 250
    assert n.age.largest == 50.0


@pytest.mark.parametrize("period", [1e-3, 2.5e-4, 1e-3 / 3])
def test_the_delay_rounds_up_to_the_next_period(period):
    # 0.0301 s each way: the answer arrives 0.0602 s later, in force from the period after it.
    n = link(0.0301, 1000, period)
    periods = -int(-0.0602 // period)  # ceil
    applied = [node.Node.through_link(n, k, float(k + 1)) for k in range(3 * periods)]
    assert applied[:periods] == [0.0] * periods
    assert applied[periods:] == [float(k - periods + 1) for k in range(periods, 3 * periods)]


def test_answers_older_than_max_age_are_never_applied():
    # 50 periods in flight, at most 10 periods old: nothing is ever applied; the 0 N m is held.
    n = link(0.025, 10)
    assert all(node.Node.through_link(n, k, 5.0) == 0.0 for k in range(200))
    assert n.c["torques_applied"] == 0


def test_without_delay_the_answer_is_applied_at_once():
    n = link(0.0, 10)
    assert [node.Node.through_link(n, k, k * 0.5) for k in range(5)] == [0.0, 0.5, 1.0, 1.5, 2.0]


@pytest.mark.parametrize(
    "argv, says",
    [
        (["--delay", "0.025"], "only with --clock lockstep"),
        (["--clock", "lockstep", "--delay", "2"], "allowed 0 to 1 s"),
        (["--clock", "lockstep", "--delay", "-0.1"], "allowed 0 to 1 s"),
    ],
)
def test_bad_delays_are_refused_naming_the_flag(argv, says, capsys):
    with pytest.raises(SystemExit) as e:
        node.main(argv)
    assert e.value.code == 1
    err = capsys.readouterr().err
    assert "--delay" in err and says in err
