"""Whose messages: the source attachment of docs/protocol.md (*Whose messages*), shared by
plant.py and controller.py.

Every put carries, as the zenoh sample's attachment, the 4 bytes `TSRC` and the publishing
session's 16-byte `ZenohId` in little-endian order (20 bytes; the payload is unchanged). zenoh
prints a `ZenohId` as that little-endian number in lowercase hexadecimal without leading zeros
(`str(session.zid())`), and takes the same text as the configuration's `id`. A receiver told a
peer's id (`--plant-id`, `--controller-id`) believes that peer's topics only from that session;
one told no id pins the session of the first believed message ([`SourcePin`], as the Rust
nodes' `tilting_proto::SourcePin`), until that session falls silent for the pin's lapse.
"""

import argparse
import re

TAG = b"TSRC"
SIZE = 20
_HEX = re.compile(r"^[0-9a-fA-F]{1,32}$")


def parse_zenoh_id(text):
    """A zenoh id as zenoh writes it (lowercase, no leading zero) from 1 to 32 hexadecimal
    digits, not all zero; ValueError naming the allowed range otherwise."""
    if not _HEX.match(text or "") or int(text, 16) == 0:
        raise ValueError(
            f"invalid zenoh id {text!r}: allowed 1 to 32 hexadecimal digits (0-9, a-f), not all zero"
        )
    return format(int(text, 16), "x")


def zenoh_id_arg(text):
    """`parse_zenoh_id` for argparse (`type=`)."""
    try:
        return parse_zenoh_id(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def id_bytes(zid):
    """The 16 little-endian bytes of a zenoh id (a `ZenohId` or its text)."""
    return int(str(zid), 16).to_bytes(16, "little")


def id_text(b):
    """A zenoh id's 16 little-endian bytes as zenoh prints the id (lowercase hex, no leading
    zero)."""
    return format(int.from_bytes(b, "little"), "x")


def attachment(zid):
    """The attachment that says "published by session `zid`": `TSRC` and the id, 20 bytes."""
    return TAG + id_bytes(zid)


def source_of(sample):
    """The 16 id bytes a sample's attachment names, or None (no attachment, another size or
    tag)."""
    a = sample.attachment
    if a is None:
        return None
    b = a.to_bytes()
    if len(b) != SIZE or b[:4] != TAG:
        return None
    return b[4:]


class SourcedPublisher:
    """A zenoh publisher whose every put carries its session's source attachment."""

    def __init__(self, session, key, **qos):
        self.publisher = session.declare_publisher(key, **qos)
        self.attachment = attachment(session.zid())

    def put(self, payload):
        self.publisher.put(payload, attachment=self.attachment)

    def undeclare(self):
        self.publisher.undeclare()


class SourcePin:
    """The session a stream is pinned to, as one receiver believes it: the Rust nodes'
    `tilting_proto::SourcePin` (proto/src/source.rs), for the 16 id bytes of `source_of`.

    - Made with `expected` (the id a node was told, `--plant-id` / `--controller-id`): pinned to
      it from the start, never lapses; a message from another session, or naming none, is
      refused.
    - Otherwise every message is admitted until a believed message names a source
      (`believe`), which pins it. While pinned, a message from another session or naming none is
      refused, unless the pinned session has said nothing believed for `lapse` seconds: then the
      pin has lapsed and the next believed message pins anew (a restarted node is a new
      session).

    Not thread-safe: the caller holds its lock around `admits` and `believe`.
    """

    def __init__(self, expected=None, lapse=0.5):
        if not (lapse > 0.0):
            raise ValueError(f"invalid lapse {lapse!r}: allowed > 0 s")
        self.lapse = lapse
        self.expected = expected is not None
        self.pinned = expected
        self.last = None

    def admits(self, source, now):
        """Whether a message from `source` (16 bytes, or None: it names none) received at
        `now` (s, a monotonic clock) may be believed."""
        if self.pinned is None or source == self.pinned:
            return True
        if self.expected:
            return False
        return now - self.last >= self.lapse

    def believe(self, source, now):
        """A message from `source` received at `now` was believed (after `admits` and every
        other rule): it pins its source, or keeps the pin alive."""
        if self.expected:
            return
        if source is not None:
            self.pinned, self.last = source, now
        elif self.pinned is not None:
            # Admitted without a source: the pin had lapsed.
            self.pinned, self.last = None, None
