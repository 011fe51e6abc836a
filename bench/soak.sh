#!/usr/bin/env bash
# Soak test of issue 22: `tilting live` for SECONDS open, then SECONDS with `--secure`, on this
# machine, no attacker. For each run it prints the safe-mode entries (the plant's watchdog
# trips), the deadline misses, the link flaps (the controller's liveliness token lost at the
# plant, and "TX task failed" / "RX task failed" of zenoh's transport in every node's log), the
# loop latency p50/p99 (state published -> torque received, the plant's last 4096 periods), the
# orbit verdict, and the resident memory (VmRSS) of each process at the start (15 s in) and the
# end (5 s before it); then the secure/open p99 ratio.
#
#   bench/soak.sh            # 600 s each (20 min in all)
#   bench/soak.sh 180        # 3 min each
#
# Env: TILTING (default ./target/release/tilting), SOAK_OUT (default runs/soak-<UTC time>).
# Build first: cargo build --release --workspace --bins
set -uo pipefail
S=${1:-600}
if ! [[ "$S" =~ ^[0-9]+$ ]] || [ "$S" -lt 30 ]; then
    echo "usage: bench/soak.sh [SECONDS >= 30]" >&2
    exit 2
fi
T=${TILTING:-./target/release/tilting}
OUT=${SOAK_OUT:-runs/soak-$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$OUT"

rss() { awk '/VmRSS/{print $2}' "/proc/$1/status" 2>/dev/null || echo "?"; }
# "name=KB ..." for `tilting live` and each of its children.
sample() {
    local out="tilting-live=$(rss "$1")"
    for c in $(pgrep -P "$1"); do
        out="$out $(cat "/proc/$c/comm" 2>/dev/null)=$(rss "$c")"
    done
    echo "$out"
}

for mode in open secure; do
    dir="$OUT/$mode"
    flags=()
    [ "$mode" = secure ] && flags=(--secure)
    echo "soak: $mode, $S s -> $dir" >&2
    RUST_LOG=warn,zenoh_transport::unicast::universal::link=debug \
        "$T" live --duration "$S" --out "$dir" "${flags[@]}" >"$OUT/$mode.stdout" 2>"$OUT/$mode.stderr" &
    pid=$!
    sleep 15
    start=$(sample "$pid")
    sleep $((S - 20))
    end=$(sample "$pid")
    wait "$pid"
    rc=$?
    tx=$(cat "$dir"/*.log "$OUT/$mode.stderr" 2>/dev/null | grep -c "TX task failed")
    rx=$(cat "$dir"/*.log "$OUT/$mode.stderr" 2>/dev/null | grep -c "RX task failed")
    python3 - "$mode" "$dir/summary.json" "$rc" "$tx" "$rx" "$start" "$end" >>"$OUT/table.txt" <<'PY'
import json, sys
mode, path, rc, tx, rx, start, end = sys.argv[1:]
try:
    s = json.load(open(path))
except Exception as e:
    print(f"{mode}: no summary ({e}); exit {rc}")
    sys.exit()
p = s.get("plant") or {}
lat = p.get("latency_us") or {}
orbit = (s.get("orbit") or {}).get("state", "?")
print(f"{mode}: exit {rc}, {s['result']}, {p.get('steps', 0)} periods; safe-mode entries "
      f"{p.get('watchdog_trips', '?')}, safe periods {p.get('safe_periods', '?')}, deadline misses "
      f"{p.get('deadline_misses', '?')}; link flaps: controller token lost {p.get('token_losses', '?')} "
      f"times at the plant, 'TX task failed' {tx}, 'RX task failed' {rx} (the last include the "
      f"links closed at the end); latency p50 {lat.get('p50', 0):.0f} us, p99 {lat.get('p99', 0):.0f} us; "
      f"orbit {orbit}")
print(f"{mode}: RSS kB at start: {start}")
print(f"{mode}: RSS kB at end:   {end}")
print(f"{mode}: p99 {lat.get('p99', 0)}")
PY
done
cat "$OUT/table.txt" | grep -v ": p99 "
python3 - "$OUT/table.txt" <<'PY'
import sys
p99 = {}
for line in open(sys.argv[1]):
    mode, _, rest = line.partition(": p99 ")
    if rest:
        p99[mode] = float(rest)
if p99.get("open"):
    print(f"secure/open latency p99: {p99.get('secure', 0) / p99['open']:.2f}x "
          f"({p99.get('secure', 0):.0f} / {p99['open']:.0f} us)")
PY
