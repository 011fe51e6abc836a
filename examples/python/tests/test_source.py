"""Whose messages in the Python nodes (examples/python/tilting_source.py): the pin of a stream's
source against the rules of docs/protocol.md (*Whose messages*), written out here, and the same
scenarios as the Rust `SourcePin`'s unit tests (proto/src/source.rs); then the plant's torque
callback (plant.py `Node.on_torque`) told no `--controller-id`: the first controller's session
holds the pin, a second one is refused and counted until the first is silent for the lockstep
timeout. Times come from a fake clock, never from the machine's speed.

Run with `python3 -m pytest -q examples/python/tests` (no zenoh needed).
"""

import importlib.util
import struct
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

import tilting_source  # noqa: E402
from tilting_source import SourcePin  # noqa: E402

A, B = bytes([1] * 16), bytes([2] * 16)


def test_the_first_believed_source_holds_the_pin_until_it_lapses():
    pin = SourcePin(lapse=0.1)
    # Nothing pinned: all admitted, and a message without a source pins nothing.
    assert pin.admits(None, 0.0) and pin.admits(B, 0.0)
    pin.believe(None, 0.0)
    assert pin.pinned is None
    pin.believe(A, 0.0)
    assert pin.pinned == A
    # Pinned to A: B and "no source" are refused while A talks, A is admitted.
    for t in (0.0, 0.05, 0.099):
        assert not pin.admits(B, t), t
        assert not pin.admits(None, t), t
        assert pin.admits(A, t), t
    # A keeps the pin alive by talking.
    pin.believe(A, 0.09)
    assert not pin.admits(B, 0.18)
    # 100 ms of silence from A: the pin lapses, B takes it, and A is the foreign one.
    assert pin.admits(B, 0.19)
    pin.believe(B, 0.19)
    assert pin.pinned == B
    assert not pin.admits(A, 0.2)
    # A lapsed pin and a believed message without a source: unpinned.
    pin.believe(None, 0.4)
    assert pin.pinned is None


def test_an_expected_source_holds_the_pin_before_any_message_and_forever():
    pin = SourcePin(A)
    # Before A's first message, B (the rogue that talks first) and "no source" are refused.
    assert not pin.admits(B, 0.0) and not pin.admits(None, 0.0)
    # Even if the caller believes them, the pin does not move.
    pin.believe(B, 0.0)
    pin.believe(None, 0.0)
    assert pin.pinned == A
    # No lapse: an hour of silence from A, B still refused; A admitted.
    assert not pin.admits(B, 3600.0) and pin.admits(A, 3600.0)
    # Without an expected source, the same rogue would have taken the pin.
    open_pin = SourcePin(None, lapse=0.5)
    assert open_pin.admits(B, 0.0)
    open_pin.believe(B, 0.0)
    assert open_pin.pinned == B


def feed(pin, events):
    """Offers `events` ((time, source), in order) to `pin`, believing each admitted one; the
    refusals per source."""
    refused = {A: 0, B: 0}
    for t, who in events:
        if pin.admits(who, t):
            pin.believe(who, t)
        else:
            refused[who] += 1
    return refused


def test_a_stream_is_refused_exactly_while_another_holds_the_pin():
    """A 1 kHz stream from A for 1 s, a second session B sending every 10 ms throughout and
    for 0.5 s after A stops, each admitted message believed. The truth, from the rule: B is
    refused while A has spoken within the lapse (0.2 s), so B's messages at or before A's last
    message + 0.2 s are refused, and every later one is admitted; A's are all admitted."""
    lapse, a_end = 0.2, 1.0
    pin = SourcePin(lapse=lapse)
    events = [(k * 1e-3, A) for k in range(1, 1001)] + [(k * 1e-2 + 5e-4, B) for k in range(150)]
    events.sort()
    refused = feed(pin, events)
    # A's first message (1 ms) comes after B's first (0.5 ms): B pinned first, so A was
    # refused until B fell silent... B never does (every 10 ms < lapse): A refused throughout.
    assert refused[A] == 1000
    assert refused[B] == 0
    assert pin.pinned == B
    # Expected A instead: B refused every time, A never.
    pin = SourcePin(A)
    refused = feed(pin, events)
    assert refused == {A: 0, B: 150}
    # A first (B joins at 0.1 s): B refused while A talks and up to 0.2 s after A's last.
    pin = SourcePin(lapse=lapse)
    events = [(k * 1e-3, A) for k in range(1, 1001)] + [
        (0.1 + k * 1e-2 + 5e-4, B) for k in range(140)
    ]
    events.sort()
    refused = feed(pin, events)
    b_times = [t for t, who in events if who == B]
    want = sum(1 for t in b_times if t - a_end < lapse)
    assert (refused[A], refused[B]) == (0, want)
    assert 0 < want < len(b_times)
    assert pin.pinned == B


def test_bad_lapse_is_refused():
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="lapse"):
            SourcePin(lapse=bad)


def load(name):
    spec = importlib.util.spec_from_file_location(name, HERE.parent / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


class Sample:
    """What `Node.on_torque` reads of a zenoh sample: the payload and the attachment."""

    def __init__(self, payload, source):
        self.payload = SimpleNamespace(to_bytes=lambda: payload)
        att = None if source is None else tilting_source.TAG + source
        self.attachment = None if att is None else SimpleNamespace(to_bytes=lambda: att)


def test_the_python_plant_pins_the_first_controller_without_an_id(monkeypatch):
    plant = load("plant")
    clock = [100.0]
    monkeypatch.setattr(plant.time, "monotonic", lambda: clock[0])
    args = SimpleNamespace(
        robot="unit",
        controller_id=None,
        lockstep_timeout_ms=50.0,
        noise_alpha=0.0,
        noise_beta=0.0,
        noise_alpha_dot=0.0,
        noise_beta_dot=0.0,
        encoder_counts=None,
        seed=0,
        measure="all",
        max_torque=100.0,
    )
    node = plant.Node(args, zenoh=None)
    torque = struct.Struct("<Qd")

    def send(seq, tau, source):
        node.waiting_for = seq
        node.on_torque(Sample(torque.pack(seq, tau), source))

    # A answers state 0 first: pinned. B's answers are refused as foreign while A talks.
    send(0, 1.0, A)
    assert node.answer == 1.0
    for seq in range(1, 11):
        clock[0] += 1e-3
        send(seq, 9.0, B)
        send(seq, 2.0, A)
        assert node.answer == 2.0, seq
    assert node.c["torques_foreign"] == 10
    # A silent for the lockstep timeout (50 ms): B, a restarted controller, takes the pin.
    clock[0] += 0.051
    send(11, 3.0, B)
    assert node.answer == 3.0
    send(12, 4.0, A)
    assert node.answer == 3.0 and node.c["torques_foreign"] == 11
    # Told the controller's id, the first talker takes nothing.
    args.controller_id = tilting_source.id_text(A)
    node = plant.Node(args, zenoh=None)
    send(0, 9.0, B)
    assert node.answer is None and node.c["torques_foreign"] == 1
    send(0, 1.0, A)
    assert node.answer == 1.0
