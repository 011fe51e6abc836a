"""The wire protocol 2 of docs/protocol.md, plant side: payloads, the session, whose messages.
Copied from examples/python/plant.py and examples/python/tilting_source.py (the reference
Python plant, tested against the Rust nodes by tests/tests/peers/python_plant.rs), trimmed to what a
plant needs."""

import argparse
import json
import math
import re
import struct

# Little-endian, no padding, no header.
PLANT_STATE = struct.Struct("<Q5d2B")  # seq, time, alpha, beta, alpha_dot, beta_dot, mode, measured
MEASURED_FULL = 15
TORQUE = struct.Struct("<Qd")  # seq, tau
MODE_EVENT = struct.Struct("<Qd2B8d")  # seq, time, from, to, x_before[4], x_after[4]
STATUS_HEAD = struct.Struct("<QdBB7Q5d3Q3dQ")  # ... then `fault` length n, n bytes of UTF-8
assert (PLANT_STATE.size, TORQUE.size, MODE_EVENT.size, STATUS_HEAD.size) == (50, 16, 82, 170)
# Status.state
STARTING, RUNNING, SAFE, FAULTED, STOPPED = 0, 1, 2, 3, 4
MAX_FAULT_BYTES = 1024
ROBOT_RE = re.compile(r"^[A-Za-z0-9_-]+$")


def pack_state(seq, t, mode, x):
    return PLANT_STATE.pack(seq, t, x[0], x[1], x[2], x[3], mode, MEASURED_FULL)


def pack_event(seq, ev):
    return MODE_EVENT.pack(seq, ev.t, ev.frm, ev.to, *ev.x_before, *ev.x_after)


def pack_status(fields, fault):
    """fields: the 22 values of the fixed part before the fault length, in table order."""
    text = fault.encode("utf-8")
    if len(text) > MAX_FAULT_BYTES:  # cut on a character boundary
        text = text[:MAX_FAULT_BYTES].decode("utf-8", "ignore").encode("utf-8")
    return STATUS_HEAD.pack(*fields, len(text)) + text


def unpack_torque(payload):
    """Decodes and validates a TorqueCommand; raises ValueError naming the problem."""
    if len(payload) != TORQUE.size:
        raise ValueError(f"TorqueCommand: wrong payload size: expected {TORQUE.size} bytes, got {len(payload)}")
    seq, tau = TORQUE.unpack(payload)
    if not math.isfinite(tau):
        raise ValueError(f"TorqueCommand.tau = {tau} is not finite")
    return seq, tau


def session_config(zenoh, listen, connect, config_file=None):
    """The session of docs/protocol.md: peer mode, multicast scouting off, gossip on, explicit
    endpoints; with `config_file` (`--zenoh-config`, e.g. the certificates of `--secure`) that
    file, with the endpoints given added."""
    if config_file:
        cfg = zenoh.Config.from_file(config_file)
        items = []
        if listen:
            items.append(("listen/endpoints", json.dumps(listen)))
        if connect:
            items.append(("connect/endpoints", json.dumps(connect)))
    else:
        cfg = zenoh.Config()
        items = [
            ("mode", '"peer"'),
            ("scouting/multicast/enabled", "false"),
            ("scouting/gossip/enabled", "true"),
            ("scouting/delay", "1000"),
            ("timestamping/enabled", "false"),
            ("connect/retry", "{period_init_ms: 100, period_max_ms: 1000, period_increase_factor: 2}"),
            ("listen/endpoints", json.dumps(listen)),
            ("connect/endpoints", json.dumps(connect)),
        ]
    # A link whose peer stops reading drops loop messages instead of stalling the loop.
    items += [
        ("transport/link/tx/queue/size/real_time", "16"),
        ("transport/link/tx/queue/congestion_control/drop/wait_before_drop", "50"),
    ]
    for key, value in items:
        cfg.insert_json5(key, value)
    return cfg


# Whose messages (docs/protocol.md): every put carries `TSRC` and the session's 16-byte zenoh id.
TAG = b"TSRC"
_HEX = re.compile(r"^[0-9a-fA-F]{1,32}$")


def zenoh_id_arg(text):
    """A zenoh id as zenoh writes it (1 to 32 hex digits, not all zero), for argparse."""
    if not _HEX.match(text or "") or int(text, 16) == 0:
        raise argparse.ArgumentTypeError(
            f"invalid zenoh id {text!r}: allowed 1 to 32 hexadecimal digits (0-9, a-f), not all zero"
        )
    return format(int(text, 16), "x")


def id_bytes(zid):
    return int(str(zid), 16).to_bytes(16, "little")


def id_text(b):
    return format(int.from_bytes(b, "little"), "x")


def source_of(sample):
    """The 16 id bytes a sample's attachment names, or None."""
    a = sample.attachment
    if a is None:
        return None
    b = a.to_bytes()
    if len(b) != 20 or b[:4] != TAG:
        return None
    return b[4:]


class SourcedPublisher:
    """A zenoh publisher whose every put carries its session's source attachment."""

    def __init__(self, session, key, **qos):
        self.publisher = session.declare_publisher(key, **qos)
        self.attachment = TAG + id_bytes(session.zid())

    def put(self, payload):
        self.publisher.put(payload, attachment=self.attachment)

    def undeclare(self):
        self.publisher.undeclare()


class SourcePin:
    """The controller's session as the plant believes it (proto/src/source.rs): pinned to
    `expected` (`--controller-id`) for good, or to the first believed source until it is silent
    for `lapse` s. Not thread-safe: the caller holds its lock."""

    def __init__(self, expected=None, lapse=0.05):
        self.lapse, self.expected, self.pinned, self.last = lapse, expected is not None, expected, None

    def admits(self, source, now):
        if self.pinned is None or source == self.pinned:
            return True
        if self.expected:
            return False
        return now - self.last >= self.lapse

    def believe(self, source, now):
        if self.expected:
            return
        if source is not None:
            self.pinned, self.last = source, now
        elif self.pinned is not None:
            self.pinned, self.last = None, None
