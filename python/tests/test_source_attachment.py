"""The Python examples name their session on every put (docs/protocol.md, *Whose messages*):
the attachment `TSRC` + the 16-byte ZenohId, little-endian, as the Rust nodes attach and parse
it (`tilting_proto::source`). The Rust side's acceptance of a Python node's messages is tested
in tests/tests/peers/python_plant.rs and python_peer.rs (the Rust node is told the Python node's id
and refuses every message that does not carry it)."""

import json
import socket
import sys
import threading
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples" / "python"))
import tilting_source  # noqa: E402


def test_attachment_layout_is_the_rust_one():
    # The same case as proto/src/source.rs's unit test: id "1ab" is the bytes ab 01 00 ...
    a = tilting_source.attachment("1ab")
    assert a == b"TSRC" + bytes([0xAB, 0x01]) + bytes(14)
    assert len(a) == tilting_source.SIZE == 20
    # The largest id: 32 hex digits, all ones.
    assert tilting_source.attachment("f" * 32) == b"TSRC" + b"\xff" * 16


@pytest.mark.parametrize("bad", ["", "0", "000", "xyz", "-1", "f" * 33, None])
def test_bad_ids_are_refused_naming_the_range(bad):
    with pytest.raises(ValueError, match="1 to 32 hexadecimal digits"):
        tilting_source.parse_zenoh_id(bad)


def test_ids_are_normalised_as_zenoh_writes_them():
    # zenoh refuses uppercase and leading zeros in its `id` field.
    assert tilting_source.parse_zenoh_id("00AB1") == "ab1"


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_python_publisher_names_its_session_and_the_receiver_reads_it():
    """A SourcedPublisher on a session opened with a chosen id: every sample a second session
    receives carries TSRC + that id's little-endian bytes, computed independently from the hex
    text (reversed big-endian digits), and equal to what `str(session.zid())` says."""
    zenoh = pytest.importorskip("zenoh")
    port = free_port()
    chosen = "c0ffee0123456789abcdef0123456789"

    def config(listen, connect, zid=None):
        cfg = zenoh.Config()
        cfg.insert_json5("scouting/multicast/enabled", "false")
        cfg.insert_json5("listen/endpoints", json.dumps(listen))
        cfg.insert_json5("connect/endpoints", json.dumps(connect))
        if zid:
            cfg.insert_json5("id", json.dumps(zid))
        return cfg

    pub_session = zenoh.open(config([f"tcp/127.0.0.1:{port}"], [], chosen))
    sub_session = zenoh.open(config([], [f"tcp/127.0.0.1:{port}"]))
    try:
        assert str(pub_session.zid()) == chosen
        got, seen = [], threading.Event()

        def on_sample(sample):
            got.append((bytes(sample.payload.to_bytes()), tilting_source.source_of(sample)))
            seen.set()

        sub = sub_session.declare_subscriber("tilting/pytest/plant/state", on_sample)
        pub = tilting_source.SourcedPublisher(pub_session, "tilting/pytest/plant/state")
        # Put until one arrives (the subscription needs a moment to reach the publisher).
        for _ in range(200):
            pub.put(b"x")
            if seen.wait(0.05):
                break
        assert got, "no sample within 10 s"
        want = bytes.fromhex(chosen)[::-1]
        assert all(src == want for _, src in got), got
        # A plain put names no source.
        plain = []
        sub2 = sub_session.declare_subscriber(
            "tilting/pytest/plain", lambda s: plain.append(tilting_source.source_of(s))
        )
        raw = pub_session.declare_publisher("tilting/pytest/plain")
        for _ in range(200):
            raw.put(b"y")
            if plain:
                break
            threading.Event().wait(0.05)
        assert plain and all(p is None for p in plain), plain
        for x in (sub, sub2, pub, raw):
            x.undeclare()
    finally:
        pub_session.close()
        sub_session.close()
