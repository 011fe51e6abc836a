#!/usr/bin/env python3
"""An independent Foxglove WebSocket client for the tests of `tilting live --foxglove`.

It speaks the documented protocol (foxglove.websocket.v1, which the SDK calls foxglove.sdk.v1: JSON text frames `serverInfo`,
`advertise`, `status`; client `subscribe`; binary `MessageData` frames = opcode 0x01, u32
subscription id, u64 log time in ns, payload, little-endian) with the `websockets` package, and
decodes every message against the schema its channel advertised: JSON messages with
`jsonschema`, protobuf messages (foxglove.SceneUpdate, FrameTransforms, Log) with message
classes built from the advertised FileDescriptorSet (`protobuf`). Nothing here comes from the
server's code.

Usage: foxglove_client.py --url ws://127.0.0.1:PORT --robot NAME --seconds S --out FILE.json
       [--unknown-channel] [--disconnect-after S] [--all]

It connects (retrying until --seconds runs out), subscribes to the state, scene, tf and log
channels, collects until --seconds pass or the server closes, and writes what it received as
JSON. Exit code 3 when a Python package is missing (the test then skips).
"""

import argparse
import base64
import json
import struct
import sys
import time

try:
    import jsonschema
    from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    from websockets.sync.client import connect
except ImportError as e:  # the test skips
    print(f"missing Python package: {e}", file=sys.stderr)
    sys.exit(3)

# The SDK's servers (0.30) speak `foxglove.sdk.v1`: the protocol of `foxglove.websocket.v1` under
# a new name. Both are offered; the server picks.
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]


def protobuf_class(name, schema_b64):
    fds = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(schema_b64))
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def vec(v):
    return [v.x, v.y, v.z]


def quat(q):
    return [q.x, q.y, q.z, q.w]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--url", required=True)
    ap.add_argument("--robot", required=True)
    ap.add_argument("--seconds", type=float, required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--unknown-channel", action="store_true")
    ap.add_argument("--all", action="store_true", help="subscribe to every channel")
    ap.add_argument("--disconnect-after", type=float)
    a = ap.parse_args()

    deadline = time.monotonic() + a.seconds
    # The imports are done: the test may start the server now.
    print("ready", flush=True)
    while True:
        try:
            ws = connect(a.url, subprotocols=SUBPROTOCOLS, max_size=None, open_timeout=2)
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)
    with ws:
        out = session(ws, a, deadline)
    with open(a.out, "w") as f:
        json.dump(out, f)


def session(ws, a, deadline):
    base = f"/tilting/{a.robot}"
    wanted = {
        f"{base}/plant/state": "state",
        f"{base}/scene": "scene",
        f"{base}/tf": "tf",
        f"{base}/log": "log",
        f"{base}/planner/reference": "reference",
    }
    out = {
        "subprotocol": ws.subprotocol,
        "server_info": None,
        "advertised": {},
        "states": [],
        "tf": [],
        "scene_updates": 0,
        "scene_entity_ids": [],
        "logs": [],
        "references": 0,
        "statuses": [],
        "invalid": [],
    }
    decoders = {}  # subscription id -> (kind, decode)
    subscribed = False
    stop = deadline if a.disconnect_after is None else time.monotonic() + a.disconnect_after
    while time.monotonic() < stop:
        try:
            frame = ws.recv(timeout=max(0.01, stop - time.monotonic()))
        except TimeoutError:
            break
        except Exception as e:  # the server closed: the run is over
            out["closed"] = str(e)
            break
        if isinstance(frame, str):
            msg = json.loads(frame)
            op = msg.get("op")
            if op == "serverInfo":
                out["server_info"] = msg
            elif op == "status":
                out["statuses"].append(msg)
            elif op == "advertise":
                subs = []
                for ch in msg["channels"]:
                    out["advertised"][ch["topic"]] = {
                        k: ch.get(k) for k in ("id", "encoding", "schemaName", "schemaEncoding")
                    }
                    kind = wanted.get(ch["topic"], "other" if a.all else None)
                    if kind is None:
                        continue
                    if ch["encoding"] == "json":
                        validator = jsonschema.Draft202012Validator(json.loads(ch["schema"]))

                        def dec(payload, v=validator):
                            m = json.loads(payload)
                            v.validate(m)
                            return m

                    else:
                        cls = protobuf_class(ch["schemaName"], ch["schema"])
                        dec = cls.FromString
                    sid = len(decoders) + 1
                    decoders[sid] = (kind, dec)
                    subs.append({"id": sid, "channelId": ch["id"]})
                if a.unknown_channel:
                    unknown = max(c["id"] for c in msg["channels"]) + 1000
                    subs.append({"id": 999, "channelId": unknown})
                if subs:
                    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                    subscribed = True
            continue
        if frame[0] != 0x01:
            continue
        sid, log_time = struct.unpack_from("<IQ", frame, 1)
        payload = frame[13:]
        if sid not in decoders:
            out["invalid"].append(f"unknown subscription {sid}")
            continue
        kind, dec = decoders[sid]
        try:
            m = dec(payload)
        except Exception as e:
            out["invalid"].append(f"{kind}: {e}")
            continue
        if kind == "state":
            out["states"].append(
                {k: m[k] for k in ("seq", "time", "alpha", "beta", "mode")} | {"log_time": log_time}
            )
        elif kind == "tf":
            frames = {t.child_frame_id: t for t in m.transforms}
            p, r = frames["plate"], frames["arm"]
            out["tf"].append(
                {
                    "time": p.timestamp.seconds + p.timestamp.nanos * 1e-9,
                    "log_time": log_time,
                    "plate_parent": p.parent_frame_id,
                    "arm_parent": r.parent_frame_id,
                    "plate": [vec(p.translation), quat(p.rotation)],
                    "arm": [vec(r.translation), quat(r.rotation)],
                }
            )
        elif kind == "scene":
            out["scene_updates"] += 1
            for e in m.entities:
                if e.id not in out["scene_entity_ids"]:
                    out["scene_entity_ids"].append(e.id)
        elif kind == "log":
            out["logs"].append({"level": m.level, "message": m.message})
        elif kind == "reference":
            out["references"] += 1
        else:
            out["other"] = out.get("other", 0) + 1
    out["subscribed"] = subscribed
    return out


if __name__ == "__main__":
    main()
