"""pyzeros (PyPI: a pure-Python rmw_zenoh client, not ours) against a plant run with `--ros2`
(the rmw_zenoh route; tests/tests/ros2_dds.rs, docs/ros2.md).

    pyzeros_peer.py ROBOT PORT DOMAIN SECONDS COMMANDS
    pyzeros_peer.py --warm      compile pyzeros's codecs (cydr, into CYDR_CACHE_DIR) once, as
                                .ci/run does: the first compile takes minutes on a busy machine

Connects to the plant's zenoh endpoint tcp/127.0.0.1:PORT, subscribes to /ROBOT/joint_states and
/ROBOT/contact_mode, waits for the first joint_states (discovery) and for the plant's
effort_command subscription in the graph, sends COMMANDS torques of 0 N m on
/ROBOT/effort_command 20 ms apart, listens SECONDS in all, and prints one JSON line of counts.
"""

import json
import sys
import threading
import time

import zenoh
import pyzeros
from pyzeros.pub import Pub
from pyzeros.sub import RawSub
from ros2_pyterfaces.cyclone.sensor_msgs.msg import JointState
from ros2_pyterfaces.cyclone.std_msgs.msg import Float64MultiArray, UInt8

NAMES = ["left_edge", "right_edge", "arm"]


def main(robot, port, domain, seconds, commands):
    cfg = zenoh.Config()
    cfg.insert_json5("mode", '"client"')
    cfg.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{port}"]))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    z = zenoh.open(cfg)
    node = pyzeros.Session(node="pyzeros_peer", zenoh_session=z, domain_id=domain)
    lock = threading.Lock()
    got = {"joint_states": 0, "bad_names": 0, "undecodable": 0, "contact_mode": 0, "modes_ok": True}
    first = threading.Event()

    def on_js(sample):
        try:
            m = JointState.deserialize(sample.payload.to_bytes())
        except Exception:  # noqa: BLE001
            with lock:
                got["undecodable"] += 1
            return
        with lock:
            got["joint_states"] += 1
            if list(m.name) != NAMES or len(m.position) != 3:
                got["bad_names"] += 1
        first.set()

    def on_mode(sample):
        m = UInt8.deserialize(sample.payload.to_bytes())
        with lock:
            got["contact_mode"] += 1
            got["modes_ok"] &= int(m.data) <= 2

    subs = [
        RawSub(JointState, f"/{robot}/joint_states", on_js, session=node, scope=None),
        RawSub(UInt8, f"/{robot}/contact_mode", on_mode, session=node, scope=None),
    ]
    t0 = time.monotonic()
    if not first.wait(30.0):
        print(json.dumps({"error": "no joint_states within 30 s"}), flush=True)
        return 1
    got["discovery_s"] = time.monotonic() - t0
    pub = Pub(Float64MultiArray, f"/{robot}/effort_command", session=node, scope=None)
    # The plant's subscription token in the graph (rmw_zenoh's liveliness), then a moment for
    # our publisher's declaration to reach the plant.
    key = f"@ros2_lv/{domain}/**/MS/%/%{robot}/tilting_plant/%{robot}%effort_command/**"
    for _ in range(100):
        if list(z.liveliness().get(key, timeout=1.0)):
            got["effort_subscription_seen"] = True
            break
        time.sleep(0.05)
    time.sleep(0.3)
    sent = 0
    for _ in range(commands):
        pub.publish(Float64MultiArray(data=[0.0]))
        sent += 1
        time.sleep(0.02)
    got["sent"] = sent
    time.sleep(max(0.0, t0 + seconds - time.monotonic()))
    for s in subs:
        s.close()
    pub.close()
    with lock:
        print(json.dumps(got), flush=True)
    node.close()
    return 0


def warm():
    import numpy as np
    from ros2_pyterfaces.cydr.idl import types
    from pyzeros.builtin_msgs import Attachment

    Attachment(sequence_number=types.int64(1), source_timestamp=types.int64(2),
               source_gid=np.zeros(16, dtype=np.uint8)).serialize()
    for m in (JointState(name=NAMES, position=[0.0] * 3), UInt8(data=1),
              Float64MultiArray(data=[0.0])):
        type(m).deserialize(m.serialize())
    print("pyzeros codecs compiled")
    return 0


if __name__ == "__main__":
    a = sys.argv
    if a[1:] == ["--warm"]:
        sys.exit(warm())
    sys.exit(main(a[1], int(a[2]), int(a[3]), float(a[4]), int(a[5])))
