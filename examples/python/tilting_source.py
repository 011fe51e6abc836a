"""Whose messages: the source attachment of docs/protocol.md (*Whose messages*), shared by
plant.py and controller.py.

Every put carries, as the zenoh sample's attachment, the 4 bytes `TSRC` and the publishing
session's 16-byte `ZenohId` in little-endian order (20 bytes; the payload is unchanged). zenoh
prints a `ZenohId` as that little-endian number in lowercase hexadecimal without leading zeros
(`str(session.zid())`), and takes the same text as the configuration's `id`. A receiver told a
peer's id (`--plant-id`, `--controller-id`) believes that peer's topics only from that session.
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
