#!/usr/bin/env python3
"""A plant command for `tilting live --plant-cmd` that puts a real transport delay in front of
any plant that does not emulate a link itself (the MuJoCo plant refuses `--delay`).

    tilting live --delay 0.025 --plant-cmd "python3 bench/delay_plant.py python3 -m tilting_mujoco --preset stiff"

`live` appends the flags it would give `tilting-plant`. This wrapper takes the link's flags out
of them (`--delay`, `--state-delay`, `--torque-delay` and `--seed`; any other link flag is
refused, naming it), moves the plant's `--listen tcp/127.0.0.1:PORT` to a free port, and listens
on PORT itself: a TCP proxy that writes every chunk read from one side to the other side the
given delay later, in order, each direction on its own (as `tests/src/proxy.rs`, the delaying
proxy of `tests/tests/loop/proxy.rs`). The controller connects to PORT as usual, so the states reach it
`state delay` late and its torques reach the plant `torque delay` late: the round trip of a real
network, on top of the loopback's. The plant runs unchanged as a child; its stdout (the summary)
and stderr pass through, its exit status is this command's, SIGINT/SIGTERM are forwarded.
"""
import os
import signal
import socket
import subprocess
import tempfile
import sys
import threading
import time
from collections import deque

LINK_REFUSED = ("--jitter", "--state-jitter", "--torque-jitter", "--loss", "--state-loss",
                "--torque-loss", "--loss-burst", "--state-loss-burst", "--torque-loss-burst")


def split_flags(argv):
    """The plant's argv without the link flags, and the delays (state, torque) in s."""
    out, state, torque = [], 0.0, 0.0
    i = 0
    while i < len(argv):
        a = argv[i]
        name, eq, val = a.partition("=")
        takes = name in ("--delay", "--state-delay", "--torque-delay", "--seed") + LINK_REFUSED
        if takes and not eq:
            i += 1
            val = argv[i]
        if name in LINK_REFUSED:
            sys.exit(f"delay_plant: {name}: only constant delays are emulated here")
        if name == "--delay":
            state = torque = float(val)
        elif name == "--state-delay":
            state = float(val)
        elif name == "--torque-delay":
            torque = float(val)
        elif name == "--seed":
            pass
        else:
            out.append(a)
        i += 1
    return out, state, torque


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def pump(src, dst, delay, stop):
    """Read from src, write to dst `delay` s after each read, in order."""
    q = deque()
    cv = threading.Condition()

    def writer():
        while True:
            with cv:
                while not q and not stop.is_set():
                    cv.wait(0.1)
                if not q:
                    return
                due, data = q[0]
            now = time.monotonic()
            if due > now:
                # A sleep, not a spin: a spinning thread holds the GIL, and the other three
                # threads (both directions' reader and writer) then wait for it, so messages
                # arrive in bunches (measured: 59 % of the torques superseded before applied).
                time.sleep(due - now)
            with cv:
                q.popleft()
            if data is None:
                try:
                    dst.shutdown(socket.SHUT_WR)
                except OSError:
                    pass
                return
            try:
                dst.sendall(data)
            except OSError:
                return

    w = threading.Thread(target=writer, daemon=True)
    w.start()
    while True:
        try:
            data = src.recv(65536)
        except OSError:
            data = b""
        with cv:
            q.append((time.monotonic() + delay, data or None))
            cv.notify()
        if not data:
            break
    w.join()


def serve(listener, target, state_delay, torque_delay, stop):
    while not stop.is_set():
        try:
            client, _ = listener.accept()
        except OSError:
            return
        try:
            server = socket.create_connection(target)
        except OSError:
            client.close()
            continue
        for s in (client, server):
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        # client (the controller) -> plant: torques; plant -> client: states.
        threading.Thread(target=pump, args=(client, server, torque_delay, stop), daemon=True).start()
        threading.Thread(target=pump, args=(server, client, state_delay, stop), daemon=True).start()


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: delay_plant.py PLANT_CMD... [flags live appends]")
    argv, state_delay, torque_delay = split_flags(sys.argv[1:])
    port = None
    for i, a in enumerate(argv):
        name, eq, val = a.partition("=")
        if name == "--listen":
            ep = val if eq else argv[i + 1]
            if ep.startswith("tcp/127.0.0.1:"):
                port = int(ep.rsplit(":", 1)[1])
                inner = f"tcp/127.0.0.1:{free_port()}"
                if eq:
                    argv[i] = f"--listen={inner}"
                else:
                    argv[i + 1] = inner
                target = ("127.0.0.1", int(inner.rsplit(":", 1)[1]))
            break
    if port is None:
        sys.exit("delay_plant: no --listen tcp/127.0.0.1:PORT among the plant's flags")
    # Hand the GIL over within 0.1 ms, not 5 ms (as the MuJoCo plant does).
    sys.setswitchinterval(1e-4)
    stop = threading.Event()
    listener = socket.socket()
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listener.bind(("127.0.0.1", port))
    listener.listen(8)
    print(f"delay_plant: 127.0.0.1:{port} -> {target[0]}:{target[1]}, states {state_delay} s, "
          f"torques {torque_delay} s late", file=sys.stderr, flush=True)
    threading.Thread(target=serve, args=(listener, target, state_delay, torque_delay, stop),
                     daemon=True).start()
    # The plant must not tell the other peers its own (inner) endpoint: with gossip on, the
    # controller learns it and connects there directly, around the proxy (measured: torque ages
    # of 0 periods). So the plant's session is the protocol's default with gossip off.
    fd, cfg = tempfile.mkstemp(prefix="delay_plant.", suffix=".json5")
    with os.fdopen(fd, "w") as f:
        f.write('{mode: "peer", scouting: {multicast: {enabled: false}, gossip: {enabled: false},'
                ' delay: 1000}, timestamping: {enabled: false}, connect: {retry: {period_init_ms:'
                ' 100, period_max_ms: 1000, period_increase_factor: 2}}}\n')
    argv.append(f"--zenoh-config={cfg}")
    child = subprocess.Popen(argv)

    def forward(signum, _frame):
        try:
            child.send_signal(signum)
        except OSError:
            pass

    signal.signal(signal.SIGINT, forward)
    signal.signal(signal.SIGTERM, forward)
    rc = child.wait()
    os.unlink(cfg)
    stop.set()
    listener.close()
    sys.stdout.flush()
    os._exit(rc if rc >= 0 else 128 - rc)


if __name__ == "__main__":
    main()
