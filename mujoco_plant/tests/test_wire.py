"""The plant's bytes against the worked examples of docs/protocol.md (wire.py is a copy of
examples/python/plant.py's codec: this keeps the copy honest)."""

import math

import pytest

from tilting_mujoco import wire


def test_state_is_the_worked_example():
    got = wire.pack_state(42, 1.5, 1, (0.25, math.pi / 2, -0.5, 2.0))
    want = "2a00000000000000000000000000f83f000000000000d03f182d4454fb21f93f000000000000e0bf0000000000000040010f"
    assert got.hex() == want


def test_torque_decodes_the_worked_example_and_refuses_bad_ones():
    assert wire.unpack_torque(bytes.fromhex("2a00000000000000000000000000c0bf")) == (42, -0.125)
    with pytest.raises(ValueError, match="size"):
        wire.unpack_torque(bytes(15))
    with pytest.raises(ValueError, match="not finite"):
        wire.unpack_torque(wire.TORQUE.pack(1, math.nan))


def test_status_carries_its_fault_text_after_170_bytes():
    fields = (7, 0.007, wire.FAULTED, 1) + (0,) * 7 + (0.0,) * 5 + (0,) * 3 + (0.0,) * 3
    payload = wire.pack_status(fields, "MuJoCo mjWARN_BADQACC")
    head = wire.STATUS_HEAD.unpack(payload[:170])
    assert head[-1] == len(payload) - 170 and payload[170:].decode() == "MuJoCo mjWARN_BADQACC"
    assert len(wire.pack_status(fields, "é" * 1000)) <= 170 + wire.MAX_FAULT_BYTES


def test_zenoh_ids_as_zenoh_prints_them():
    assert wire.zenoh_id_arg("00C0FFEE") == "c0ffee"
    assert wire.id_text(wire.id_bytes("c0ffee")) == "c0ffee"
    with pytest.raises(Exception):
        wire.zenoh_id_arg("0")
