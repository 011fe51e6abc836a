"""A real ROS 2 (Jazzy's rclpy over rmw_fastrtps_cpp, from PyPI wheels) against a plant run with
`--ros2 dds` (tests/tests/peers/ros2_clients.rs, tests/examples/loop_bench.rs, docs/ros2.md). Nothing
here imports our crates.

    rclpy_peer.py listen ROBOT SECONDS   joint_states, contact_mode, /rosout for SECONDS after the
                                         first joint_states, bad commands on effort_command, then
                                         robot_description as a late joiner; one JSON line
    rclpy_peer.py count ROBOT SECONDS    joint_states received in SECONDS after the first; one
                                         JSON line (loop_bench --ros2 2's subscriber)
    rclpy_peer.py controller ROBOT       the law of examples/python/controller.py through
                                         effort_command, one answer per joint_states stamp, until
                                         SIGINT; gains as JSON on stdin; one JSON line of counts
"""

import json
import math
import os
import signal
import sys
import threading
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String, UInt8
from rcl_interfaces.msg import Log

HERE = os.path.dirname(os.path.abspath(__file__))
NAMES = ["left_edge", "right_edge", "arm"]

# Deep enough that a Python callback behind a 1 kHz writer drops nothing.
DEEP = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE,
                  history=HistoryPolicy.KEEP_LAST, depth=5000)
LATCHED = QoSProfile(reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL,
                     history=HistoryPolicy.KEEP_LAST, depth=1)


def stamp_ns(m):
    return m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec


def spin_until(executor, cond, timeout):
    end = time.monotonic() + timeout
    while not cond() and time.monotonic() < end:
        executor.spin_once(timeout_sec=0.01)
    return cond()


def send_bad(node, pub, executor):
    """Commands the plant must refuse, at least 3 ms apart (far under its flood gate's 4,000/s
    with bursts of 16): 20 with two values, 20 NaN, 20 beyond any torque bound."""
    sent = {"length": 0, "nan": 0, "beyond": 0}
    for kind, data in (("length", [0.0, 0.0]), ("nan", [math.nan]), ("beyond", [1e9])):
        for _ in range(20):
            pub.publish(Float64MultiArray(data=data))
            sent[kind] += 1
            end = time.monotonic() + 0.003
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=max(0.0, end - time.monotonic()))
    return sent


def listen(robot, seconds):
    rclpy.init()
    node = rclpy.create_node("rclpy_listener")
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    got = {"joint_states": [], "modes": [], "rosout": [], "names_ok": True}
    first = [None]

    def on_js(m):
        if first[0] is None:
            first[0] = time.monotonic()
        if list(m.name) != NAMES:
            got["names_ok"] = False
        got["joint_states"].append([stamp_ns(m), list(m.position), list(m.velocity),
                                    list(m.effort)])

    node.create_subscription(JointState, f"/{robot}/joint_states", on_js, DEEP)
    node.create_subscription(UInt8, f"/{robot}/contact_mode",
                             lambda m: got["modes"].append(int(m.data)), DEEP)
    node.create_subscription(Log, "/rosout",
                             lambda m: got["rosout"].append([int(m.level), m.name, m.msg]), DEEP)
    pub = node.create_publisher(Float64MultiArray, f"/{robot}/effort_command", 10)
    if not spin_until(ex, lambda: first[0] is not None, 60.0):
        print(json.dumps({"error": "no joint_states within 60 s"}), flush=True)
        return 1
    # Wait for the plant's effort_command subscription before sending (discovery).
    spin_until(ex, lambda: pub.get_subscription_count() >= 1, 10.0)
    got["effort_subscribers"] = pub.get_subscription_count()
    got["sent_bad"] = send_bad(node, pub, ex)
    spin_until(ex, lambda: False, max(0.0, first[0] + seconds - time.monotonic()))
    # Then what is still queued for us: Python behind a 1 kHz writer on a busy machine lags by
    # tenths of a second (measured 0.43 s), and the window is judged by the states' stamps.
    stamp0 = min(j[0] for j in got["joint_states"])
    spin_until(ex, lambda: max(j[0] for j in got["joint_states"]) >= stamp0 + seconds * 1e9, 10.0)
    # A late joiner: robot_description is transient local, so it still gets the URDF.
    desc = []
    node.create_subscription(String, f"/{robot}/robot_description",
                             lambda m: desc.append(m.data), LATCHED)
    spin_until(ex, lambda: bool(desc), 10.0)
    got["robot_description"] = desc[0] if desc else None
    got["node_names"] = sorted(f"{ns.rstrip('/')}/{n}"
                               for n, ns in node.get_node_names_and_namespaces())
    print(json.dumps(got), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def controller(robot):
    sys.path.insert(0, os.path.join(HERE, "..", "..", "examples", "python"))
    import controller as law_py  # the law, written in Python from docs/model.md

    a = json.loads(sys.stdin.readline())
    law = law_py.ComputedTorquePD(kp=a["kp"], kd=a["kd"], k=a["k"], energy_avg=a["energy_avg"])
    rclpy.init()
    node = rclpy.create_node("rclpy_controller")
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    pub = node.create_publisher(Float64MultiArray, f"/{robot}/effort_command", 10)
    counts = {"joint_states": 0, "answered": 0, "unpaired": 0}
    # joint_states and contact_mode of one state carry the same publication sequence number
    # (one writer each, one sample each per state): whichever half comes second completes it.
    halves = {}
    last = [None]

    def answer(m, mode):
        # One answer per state: a re-publication of the state the plant waits for (lockstep,
        # every 100 ms until answered) has the same stamp.
        s = stamp_ns(m)
        if last[0] is not None and s <= last[0]:
            return
        last[0] = s
        p, v = list(m.position), list(m.velocity)
        x = (p[0] + p[1], p[2], v[0] + v[1], v[2])
        pub.publish(Float64MultiArray(data=[law.torque(mode, x)]))
        counts["answered"] += 1

    def half(info, what, value):
        n = info["publication_sequence_number"]
        other = halves.pop(n, None)
        if other is None:
            halves[n] = (what, value)
            return
        pair = dict([other, (what, value)])
        answer(pair["js"], pair["mode"])

    def on_js(m, info):
        counts["joint_states"] += 1
        if list(m.name) == NAMES:
            half(info, "js", m)

    node.create_subscription(JointState, f"/{robot}/joint_states", on_js, DEEP)
    node.create_subscription(UInt8, f"/{robot}/contact_mode",
                             lambda m, info: half(info, "mode", int(m.data)), DEEP)
    done = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: done.set())
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    while not done.is_set():
        ex.spin_once(timeout_sec=0.05)
    counts["unpaired"] = len(halves)
    print(json.dumps(counts), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def count(robot, seconds):
    """joint_states received in SECONDS after the first (a subscriber for loop_bench)."""
    rclpy.init()
    node = rclpy.create_node("rclpy_counter")
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    got = [0]
    first = [None]

    def on_js(_m):
        if first[0] is None:
            first[0] = time.monotonic()
        got[0] += 1

    node.create_subscription(JointState, f"/{robot}/joint_states", on_js, DEEP)
    if not spin_until(ex, lambda: first[0] is not None, 60.0):
        print(json.dumps({"error": "no joint_states within 60 s"}), flush=True)
        return 1
    spin_until(ex, lambda: False, max(0.0, first[0] + seconds - time.monotonic()))
    print(json.dumps({"joint_states": got[0]}), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


def main(argv):
    if argv[1] == "listen":
        return listen(argv[2], float(argv[3]))
    if argv[1] == "count":
        return count(argv[2], float(argv[3]))
    if argv[1] == "controller":
        return controller(argv[2])
    print(f"unknown mode {argv[1]!r}: allowed listen, count, controller", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
