#!/usr/bin/env python3
"""Independent check of a tilting MCAP recording with the `mcap` package (pip install mcap
zstandard), the reference reader of the format, not our Rust code.

Usage: check_mcap.py FILE.mcap

Reads the file record by record (so a file whose writer was killed reads up to its last whole
chunk), and prints one JSON object:
  {"complete": bool, "error": str|null,
   "channels": {topic: {"message_encoding", "schema_name", "schema_encoding", "count",
                        "fields_ok": bool, "first_log_time", "last_log_time"}},
   "state_seq_consecutive": bool}
"fields_ok" says every message is a JSON object with every key of the schema's "required"
list, no key the schema does not name, and values of the schema's JSON types (one type per
field, as Foxglove's parser requires).
"""
import json
import sys

from mcap.records import Channel, Footer, Message, Schema
from mcap.stream_reader import StreamReader


def type_ok(value, ty):
    if not isinstance(ty, str):
        return False  # Foxglove's and Lichtblick's parsers take one type per field
    if ty == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if ty == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if ty == "string":
        return isinstance(value, str)
    if ty == "array":
        return isinstance(value, list) and all(isinstance(v, (int, float)) for v in value)
    return False


def main(path):
    schemas, channels, out = {}, {}, {}
    complete, error = False, None
    last_seq = None
    seq_ok = True
    with open(path, "rb") as f:
        try:
            for rec in StreamReader(f).records:
                if isinstance(rec, Schema):
                    schemas[rec.id] = rec
                elif isinstance(rec, Channel):
                    # The summary section repeats the channels: count them once.
                    channels[rec.id] = rec
                    s = schemas.get(rec.schema_id)
                    out.setdefault(rec.topic, {
                        "message_encoding": rec.message_encoding,
                        "schema_name": s.name if s else None,
                        "schema_encoding": s.encoding if s else None,
                        "count": 0,
                        "fields_ok": True,
                        "first_log_time": None,
                        "last_log_time": None,
                    })
                elif isinstance(rec, Message):
                    ch = channels[rec.channel_id]
                    c = out[ch.topic]
                    c["count"] += 1
                    if c["first_log_time"] is None:
                        c["first_log_time"] = rec.log_time
                    c["last_log_time"] = rec.log_time
                    schema = json.loads(schemas[ch.schema_id].data)
                    msg = json.loads(rec.data)
                    props = schema["properties"]
                    # Every required key, no key the schema does not name (a rate the plant
                    # did not measure is left out: optional in the schema).
                    if not set(schema["required"]) <= set(msg) <= set(props) or not all(
                        type_ok(msg[k], props[k]["type"]) for k in msg
                    ):
                        c["fields_ok"] = False
                    if ch.topic.endswith("/plant/state"):
                        if last_seq is not None and msg["seq"] != last_seq + 1:
                            seq_ok = False
                        last_seq = msg["seq"]
                elif isinstance(rec, Footer):
                    complete = True
        except Exception as e:  # a torn last record: everything before it was read
            error = f"{type(e).__name__}: {e}"
    print(json.dumps({"complete": complete, "error": error, "channels": out,
                      "state_seq_consecutive": seq_ok}))


if __name__ == "__main__":
    main(sys.argv[1])
