#!/usr/bin/env python3
"""An independent ROS 2 peer for tests/tests/peers/ros2.rs, written from rmw_zenoh's conventions
(docs/ros2.md) with PyPI's `rosbags` (CDR, RIHS01 type hashes) and `eclipse-zenoh`, `xxhash`,
and none of our crates.

Modes (each prints one JSON object on stdout):
  hashes                      rosbags' hash_rihs01 of the types named on stdin (one per line),
                              for the Jazzy and the Kilted type stores
  decode TYPE                 decodes the CDR payload in hex on stdin with rosbags
  encode-effort VALUES...     a Float64MultiArray payload (hex) encoded by rosbags
  probe ROBOT PORT DOMAIN     subscribes to the robot's topics on their exact keys for a while,
                              checks attachments, sequence numbers and GIDs against the tokens of
                              a liveliness query on @ros2_lv/**, then sends bad effort commands
  controller ROBOT PORT DOMAIN  keeps the orbit: the law of examples/python/controller.py on
                              joint_states + contact_mode, answered on effort_command
"""

import json
import math
import os
import signal
import struct
import sys
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))

ADMIN_SPACE = "@ros2_lv"
KINDS = {"NN", "MP", "MS", "SS", "SC"}


def typestore(which="jazzy"):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_KILTED if which == "kilted" else Stores.ROS2_JAZZY)


def dds_name(ros_type):
    """`pkg/msg/Name` -> `pkg::msg::dds_::Name_` (rmw_zenoh's keys and tokens)."""
    pkg, sub, name = ros_type.split("/")
    return f"{pkg}::{sub}::dds_::{name}_"


def topic_key(domain, topic, ros_type, ts):
    return f"{domain}/{topic.strip('/')}/{dds_name(ros_type)}/{ts.hash_rihs01(ros_type)}"


def parse_qos(s):
    """rmw_zenoh's keyexpr_to_qos: 6 ':' parts; history, deadline, lifespan 2 ',' fields, liveliness 3."""
    parts = s.split(":")
    if len(parts) < 6:
        raise ValueError(f"QoS {s!r}: {len(parts)} parts")
    need = {2: 2, 3: 2, 4: 2, 5: 3}
    fields = {i: parts[i].split(",") for i in need}
    for i, n in need.items():
        if len(fields[i]) < n:
            raise ValueError(f"QoS {s!r}: part {i} has {len(fields[i])} fields")
    enums = [(parts[0], {"0", "1", "2", "3"}), (parts[1], {"0", "1", "2", "3"}),
             (fields[2][0], {"0", "1", "2", "3"}), (fields[5][0], {"0", "1", "3", "4", "5"})]
    for v, allowed in enums:
        if v and v not in allowed:
            raise ValueError(f"QoS {s!r}: {v!r} not in {sorted(allowed)}")
    for v in [fields[2][1], *fields[3], *fields[4], *fields[5][1:]]:
        if v and not v.isdigit():
            raise ValueError(f"QoS {s!r}: {v!r} is not a number")
    return {"reliability": parts[0], "durability": parts[1], "depth": fields[2][1]}


def parse_token(key):
    """rmw_zenoh's Entity::make(keyexpr): >= 9 parts, none empty, admin space, kind; topics 13."""
    parts = key.split("/")
    if len(parts) < 9:
        raise ValueError(f"{key}: {len(parts)} parts")
    if any(p == "" for p in parts):
        raise ValueError(f"{key}: empty part")
    if parts[0] != ADMIN_SPACE or parts[5] not in KINDS:
        raise ValueError(f"{key}: admin space or kind")
    int(parts[1])
    e = {"domain": int(parts[1]), "zid": parts[2], "nid": parts[3], "eid": parts[4],
         "kind": parts[5], "enclave": parts[6].replace("%", "/"),
         "namespace": parts[7].replace("%", "/"), "node": parts[8].replace("%", "/")}
    if parts[5] != "NN":
        if len(parts) < 13:
            raise ValueError(f"{key}: {len(parts)} parts for a topic")
        e.update(topic=parts[9].replace("%", "/"), type=parts[10].replace("%", "/"),
                 hash=parts[11].replace("%", "/"), qos=parse_qos(parts[12]))
    return e


def gid_of(token):
    """XXH3-128 of the token: low 64 bits, then high 64 bits, each little endian."""
    import xxhash

    h = xxhash.xxh3_128_intdigest(token.encode())
    return struct.pack("<QQ", h & (2**64 - 1), h >> 64)


def attachment(seq, ts_ns, gid):
    return struct.pack("<qqB", seq, ts_ns, 16) + gid


def read_attachment(sample):
    a = sample.attachment
    if a is None:
        raise ValueError("no attachment")
    b = a.to_bytes()
    if len(b) != 33 or b[16] != 0x10:
        raise ValueError(f"attachment {b.hex()}: not 33 bytes with 0x10 at 16")
    seq, ts = struct.unpack_from("<qq", b)
    return seq, ts, b[17:]


def session(port):
    import zenoh

    cfg = zenoh.Config()
    for key, value in (
        ("mode", '"peer"'),
        ("scouting/multicast/enabled", "false"),
        ("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"])),
        ("listen/endpoints", json.dumps(["tcp/127.0.0.1:0"])),
    ):
        cfg.insert_json5(key, value)
    return zenoh.open(cfg)


def effort_payload(ts, values):
    F = ts.types["std_msgs/msg/Float64MultiArray"]
    L = ts.types["std_msgs/msg/MultiArrayLayout"]
    import numpy as np

    msg = F(layout=L(dim=[], data_offset=0), data=np.array(values, dtype=np.float64))
    return bytes(ts.serialize_cdr(msg, "std_msgs/msg/Float64MultiArray"))


class Node:
    """A ROS 2 node of our own: its NN token and the MP token of effort_command."""

    def __init__(self, s, domain, robot, name):
        self.s, self.domain, self.robot = s, domain, robot
        self.zid = str(s.info.zid())
        base = f"{ADMIN_SPACE}/{domain}/{self.zid}/0"
        self.tokens = [s.liveliness().declare_token(f"{base}/0/NN/%/%{robot}/{name}")]
        self.base, self.name, self.eid = base, name, 1

    def publisher(self, topic, ros_type, ts, qos="2::,1:,:,:,,"):
        import zenoh

        tok = (f"{self.base}/{self.eid}/MP/%/%{self.robot}/{self.name}/{topic.replace('/', '%')}/"
               f"{dds_name(ros_type)}/{ts.hash_rihs01(ros_type)}/{qos}")
        self.eid += 1
        self.tokens.append(self.s.liveliness().declare_token(tok))
        pub = self.s.declare_publisher(topic_key(self.domain, topic, ros_type, ts),
                                       congestion_control=zenoh.CongestionControl.BLOCK,
                                       express=True)
        return pub, gid_of(tok)


def probe(robot, port, domain):
    ts = typestore()
    s = session(port)
    js_key = topic_key(domain, f"/{robot}/joint_states", "sensor_msgs/msg/JointState", ts)
    cm_key = topic_key(domain, f"/{robot}/contact_mode", "std_msgs/msg/UInt8", ts)
    lg_key = topic_key(domain, "/rosout", "rcl_interfaces/msg/Log", ts)
    got = {"joint_states": [], "contact_mode": [], "rosout": []}
    problems = []
    lock = threading.Lock()

    def on(name, rtype):
        def cb(sample):
            try:
                seq, stamp, gid = read_attachment(sample)
                msg = ts.deserialize_cdr(sample.payload.to_bytes(), rtype)
            except Exception as e:  # noqa: BLE001 - every problem is a finding
                with lock:
                    problems.append(f"{name}: {e}")
                return
            with lock:
                got[name].append((seq, stamp, gid, msg))
        return cb

    subs = [s.declare_subscriber(js_key, on("joint_states", "sensor_msgs/msg/JointState")),
            s.declare_subscriber(cm_key, on("contact_mode", "std_msgs/msg/UInt8")),
            s.declare_subscriber(lg_key, on("rosout", "rcl_interfaces/msg/Log"))]
    deadline = time.monotonic() + 20.0
    while time.monotonic() < deadline:
        time.sleep(0.1)
        with lock:
            if len(got["joint_states"]) >= 500:
                break
    # The bad commands; the valid ones of the flood end the safe mode for a moment (INFO on
    # /rosout), which comes back 50 periods later (WARN).
    sent_bad = send_bad(s, ts, robot, domain)
    deadline = time.monotonic() + 10.0
    while time.monotonic() < deadline:
        time.sleep(0.1)
        with lock:
            if any(g[3].level == 30 for g in got["rosout"]):
                break
    tokens = [str(r.ok.key_expr) for r in s.liveliness().get("@ros2_lv/**", timeout=5.0) if r.ok]
    parsed, bad_tokens = [], []
    for t in tokens:
        try:
            parsed.append((t, parse_token(t)))
        except (ValueError, IndexError) as e:
            bad_tokens.append(f"{t}: {e}")
    with lock:
        result = {"problems": problems[:10], "bad_tokens": bad_tokens, "tokens": tokens}
        for name in got:
            seqs = [g[0] for g in got[name]]
            result[name] = {
                "count": len(seqs),
                "consecutive": all(b == a + 1 for a, b in zip(seqs, seqs[1:])),
                "unique": len(set(seqs)) == len(seqs),
                "span": (max(seqs) - min(seqs) + 1) if seqs else 0,
                "first_seq": seqs[0] if seqs else None,
                "gids": sorted({g[2].hex() for g in got[name]}),
            }
            topic = {"joint_states": f"/{robot}/joint_states",
                     "contact_mode": f"/{robot}/contact_mode", "rosout": "/rosout"}[name]
            pubs = [(t, e) for t, e in parsed if e["kind"] == "MP" and e.get("topic") == topic]
            result[name]["token_gids"] = sorted(gid_of(t).hex() for t, _ in pubs)
            result[name]["token_qos"] = [e["qos"] for _, e in pubs]
            result[name]["token_hashes"] = sorted({e["hash"] for _, e in pubs})
        js = [g[3] for g in got["joint_states"]]
        result["joint_names"] = list(js[-1].name) if js else []
        result["positions_finite"] = all(all(math.isfinite(v) for v in m.position) for m in js)
        result["modes"] = sorted({int(g[3].data) for g in got["contact_mode"]})
        result["rosout"]["lines"] = [(int(g[3].level), g[3].name, g[3].msg) for g in got["rosout"]][:10]
        result["effort_sub_tokens"] = [
            e for _, e in parsed if e["kind"] == "MS" and e.get("topic") == f"/{robot}/effort_command"]
        result["hash_expected"] = {
            n: ts.hash_rihs01(t) for n, t in (("joint_states", "sensor_msgs/msg/JointState"),
                                              ("contact_mode", "std_msgs/msg/UInt8"),
                                              ("rosout", "rcl_interfaces/msg/Log"))}
    result["sent_bad"] = sent_bad
    for sub in subs:
        sub.undeclare()
    s.close()
    print(json.dumps(result), flush=True)


def send_bad(s, ts, robot, domain):
    """Bad effort commands, 20 of each kind, then a flood of 300 valid ones at once."""
    node = Node(s, domain, robot, "bad_peer")
    pub, gid = node.publisher(f"/{robot}/effort_command", "std_msgs/msg/Float64MultiArray", ts)
    time.sleep(0.5)  # the plant's subscriber sees our declaration
    sent = {"length": 0, "nan": 0, "stale": 0, "future": 0, "no_attachment": 0, "flood": 0}
    seq = 0

    def put(values, dt_ns=0, att=True):
        nonlocal seq
        seq += 1
        a = attachment(seq, time.time_ns() + dt_ns, gid) if att else None
        pub.put(effort_payload(ts, values), attachment=a)

    for _ in range(20):
        put([1.0, 2.0]); sent["length"] += 1
        put([float("nan")]); sent["nan"] += 1
        put([0.5], dt_ns=-2_000_000_000); sent["stale"] += 1
        put([0.5], dt_ns=2_000_000_000); sent["future"] += 1
        put([0.5], att=False); sent["no_attachment"] += 1
        time.sleep(0.01)
    time.sleep(0.05)
    for _ in range(300):
        put([0.0]); sent["flood"] += 1
    time.sleep(0.5)
    for t in node.tokens:
        t.undeclare()
    pub.undeclare()
    return sent


def controller(robot, port, domain):
    sys.path.insert(0, os.path.join(HERE, "..", "..", "examples", "python"))
    import controller as law_py  # the law, written in Python from docs/model.md

    a = json.loads(sys.stdin.readline())
    law = law_py.ComputedTorquePD(kp=a["kp"], kd=a["kd"], k=a["k"], energy_avg=a["energy_avg"])
    ts = typestore()
    s = session(port)
    node = Node(s, domain, robot, "py_controller")
    pub, gid = node.publisher(f"/{robot}/effort_command", "std_msgs/msg/Float64MultiArray", ts)
    counts = {"joint_states": 0, "answered": 0, "bad": 0}
    lock = threading.Lock()
    # The n-th contact_mode sample belongs to the n-th joint_states sample (attachment sequence
    # numbers; one mirror publishes both per state). The callbacks of two subscribers may run on
    # two threads: whichever half of a pair comes second completes it.
    halves = {}
    seq = [0]
    names = ["left_edge", "right_edge", "arm"]

    last = [None]

    def answer(m, mode):
        if list(m.name) != names:
            return
        # One answer per state: a re-publication of the state the plant waits for (lockstep,
        # every 100 ms until answered) has the same stamp. A second answer would arrive after
        # the next state and count as its answer (the plant pairs by source timestamp).
        stamp = (m.header.stamp.sec, m.header.stamp.nanosec)
        with lock:
            if last[0] is not None and stamp <= last[0]:
                return
            last[0] = stamp
        p, v = list(m.position), list(m.velocity)
        alpha = p[0] + p[1]  # one of the two edge joints is always zero
        x = (alpha, p[2], v[0] + v[1], v[2])
        tau = law.torque(mode, x)
        with lock:
            seq[0] += 1
            n = seq[0]
            counts["answered"] += 1
        pub.put(effort_payload(ts, [tau]), attachment=attachment(n, time.time_ns(), gid))

    def half(n, what, value):
        with lock:
            other = halves.pop(n, None)
            if other is None:
                halves[n] = (what, value)
                return None
        return dict([other, (what, value)])

    def on_js(sample):
        try:
            n = read_attachment(sample)[0]
            m = ts.deserialize_cdr(sample.payload.to_bytes(), "sensor_msgs/msg/JointState")
        except Exception:  # noqa: BLE001
            with lock:
                counts["bad"] += 1
            return
        with lock:
            counts["joint_states"] += 1
        pair = half(n, "js", m)
        if pair:
            answer(pair["js"], pair["mode"])

    def on_mode(sample):
        try:
            n = read_attachment(sample)[0]
            mode = int(ts.deserialize_cdr(sample.payload.to_bytes(), "std_msgs/msg/UInt8").data)
        except Exception:  # noqa: BLE001
            with lock:
                counts["bad"] += 1
            return
        pair = half(n, "mode", mode)
        if pair:
            answer(pair["js"], pair["mode"])

    subs = [
        s.declare_subscriber(topic_key(domain, f"/{robot}/joint_states",
                                       "sensor_msgs/msg/JointState", ts), on_js),
        s.declare_subscriber(topic_key(domain, f"/{robot}/contact_mode",
                                       "std_msgs/msg/UInt8", ts), on_mode),
    ]
    done = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: done.set())
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    while not done.wait(0.2):
        pass
    for sub in subs:
        sub.undeclare()
    for t in node.tokens:
        t.undeclare()
    pub.undeclare()
    s.close()
    with lock:
        print(json.dumps(counts), flush=True)


def main(argv):
    mode = argv[1]
    if mode == "hashes":
        names = [l.strip() for l in sys.stdin if l.strip()]
        print(json.dumps({w: {n: typestore(w).hash_rihs01(n) for n in names}
                          for w in ("jazzy", "kilted")}))
    elif mode == "decode":
        ts = typestore()
        msg = ts.deserialize_cdr(bytes.fromhex(sys.stdin.read().strip()), argv[2])
        out = {}
        for k in msg.__dataclass_fields__:
            v = getattr(msg, k)
            if hasattr(v, "tolist"):
                v = v.tolist()
            elif hasattr(v, "__dataclass_fields__"):
                v = {kk: (getattr(v, kk) if not hasattr(getattr(v, kk), "__dataclass_fields__")
                          else {a: getattr(getattr(v, kk), a) for a in getattr(v, kk).__dataclass_fields__})
                     for kk in v.__dataclass_fields__}
            elif isinstance(v, list):
                v = list(v)
            out[k] = v
        print(json.dumps(out))
    elif mode == "encode-effort":
        print(json.dumps({"hex": effort_payload(typestore(), [float(v) for v in argv[2:]]).hex()}))
    elif mode == "probe":
        probe(argv[2], int(argv[3]), int(argv[4]))
    elif mode == "controller":
        controller(argv[2], int(argv[3]), int(argv[4]))
    else:
        raise SystemExit(f"unknown mode {mode!r}")


if __name__ == "__main__":
    main(sys.argv)
