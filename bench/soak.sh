#!/usr/bin/env bash
# Soak test of issue 22: `tilting live` open and `tilting live --secure`, SECONDS each, in
# PAIRS interleaved pairs (open then secure, secure then open, ...: a drift of the machine's
# load falls on both modes alike), on this machine, no attacker. For each run it prints the
# safe-mode entries (the plant's watchdog trips), the deadline misses, the link flaps (the
# controller's liveliness token lost at the plant, and "TX task failed" / "RX task failed" of
# zenoh's transport in every node's log), the loop latency p50/p99 (state published -> torque
# received) twice: over the plant's last 4096 periods (its summary), and over the whole run
# (the median and the largest of the p99s of the 4096-period windows the status line shows
# once a second, from 10 s in), the orbit verdict, the router's nice value, the load average,
# and the resident memory (VmRSS) of each process at the start (15 s in) and the end (5 s
# before it); then each pair's secure/open latency ratios and their median.
#
#   bench/soak.sh              # 600 s each, one pair (20 min in all): issue 22's soak
#   bench/soak.sh 60 3         # three pairs of 1 min each (6 min in all)
#
# Env: TILTING (default ./target/release/tilting), SOAK_OUT (default runs/soak-<UTC time>).
# Build first: cargo build --release --workspace --bins
set -uo pipefail
S=${1:-600}
PAIRS=${2:-1}
if ! [[ "$S" =~ ^[0-9]+$ ]] || [ "$S" -lt 30 ] || ! [[ "$PAIRS" =~ ^[0-9]+$ ]] || [ "$PAIRS" -lt 1 ]; then
    echo "usage: bench/soak.sh [SECONDS >= 30] [PAIRS >= 1]" >&2
    exit 2
fi
T=${TILTING:-./target/release/tilting}
if ! [ -x "$T" ]; then
    echo "soak: no $T (build first: cargo build --release --workspace --bins)" >&2
    exit 2
fi
OUT=${SOAK_OUT:-runs/soak-$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$OUT"
: >"$OUT/table.txt"

rss() { awk '/VmRSS/{print $2}' "/proc/$1/status" 2>/dev/null || echo "?"; }
# "name=KB ..." for `tilting live` and each of its children.
sample() {
    local out="tilting-live=$(rss "$1")"
    for c in $(pgrep -P "$1"); do
        out="$out $(cat "/proc/$c/comm" 2>/dev/null)=$(rss "$c")"
    done
    echo "$out"
}
load() { cut -d' ' -f1 /proc/loadavg; }

# run PAIR MODE: one `tilting live` run, its line appended to table.txt.
run() {
    local pair=$1 mode=$2
    local dir="$OUT/$pair-$mode" flags=()
    [ "$mode" = secure ] && flags=(--secure)
    echo "soak: pair $pair, $mode, $S s -> $dir" >&2
    local load0
    load0=$(load)
    RUST_LOG=warn,zenoh_transport::unicast::universal::link=debug \
        "$T" live --duration "$S" --out "$dir" "${flags[@]}" >"$dir.stdout" 2>"$dir.stderr" &
    local pid=$!
    sleep 15
    local start end
    start=$(sample "$pid")
    sleep $((S - 20))
    end=$(sample "$pid")
    wait "$pid"
    local rc=$?
    local tx rx
    tx=$(cat "$dir"/*.log "$dir.stderr" 2>/dev/null | grep -c "TX task failed")
    rx=$(cat "$dir"/*.log "$dir.stderr" 2>/dev/null | grep -c "RX task failed")
    python3 - "$pair" "$mode" "$dir" "$rc" "$tx" "$rx" "$start" "$end" "$load0" "$(load)" \
        >>"$OUT/table.txt" <<'PY'
import json, sys
pair, mode, d, rc, tx, rx, start, end, l0, l1 = sys.argv[1:]
tag = f"{pair} {mode:6}"
try:
    s = json.load(open(f"{d}/summary.json"))
except Exception as e:
    print(f"{tag}: no summary ({e}); exit {rc}")
    sys.exit()
nice = "-"
try:
    for line in open(f"{d}/router.json"):
        nice = json.loads(line).get("nice", nice)
except (OSError, ValueError):
    pass
p = s.get("plant") or {}
lat = p.get("latency_us") or {}
orbit = (s.get("orbit") or {}).get("state", "?")
# The status line's windows over the run: "t   12.34 s | ... | latency p50 X us p99 Y us".
import re, statistics
win = []
try:
    for line in open(f"{d}.stderr", errors="replace"):
        m = re.search(r"t +([0-9.]+) s \|.*latency p50 ([0-9.]+) us p99 ([0-9.]+) us", line)
        if m and float(m.group(1)) >= 10.0:
            win.append((float(m.group(2)), float(m.group(3))))
except OSError:
    pass
run50 = statistics.median(w[0] for w in win) if win else 0.0
run99 = statistics.median(w[1] for w in win) if win else 0.0
max99 = max((w[1] for w in win), default=0.0)
print(f"{tag}: exit {rc}, {s['result']}, {p.get('steps', 0)} periods; safe-mode entries "
      f"{p.get('watchdog_trips', '?')}, safe periods {p.get('safe_periods', '?')}, deadline misses "
      f"{p.get('deadline_misses', '?')}; link flaps: controller token lost "
      f"{p.get('token_losses', '?')} times at the plant, 'TX task failed' {tx}, 'RX task failed' "
      f"{rx} (these include the links closed at the end); latency p50 {lat.get('p50', 0):.0f} us, "
      f"p99 {lat.get('p99', 0):.0f} us (last 4096 periods); over the run ({len(win)} windows): "
      f"median p50 {run50:.0f} us, median p99 {run99:.0f} us, largest p99 {max99:.0f} us; "
      f"orbit {orbit}; router nice {nice}; load {l0} -> {l1}")
print(f"{tag}: RSS kB at start: {start}")
print(f"{tag}: RSS kB at end:   {end}")
print(f"{tag}: latency {lat.get('p50', 0)} {lat.get('p99', 0)} {run50} {run99}")
PY
}

for pair in $(seq 1 "$PAIRS"); do
    if [ $((pair % 2)) = 1 ]; then order="open secure"; else order="secure open"; fi
    for mode in $order; do
        run "$pair" "$mode"
    done
done
grep -v ": latency " "$OUT/table.txt"
python3 - "$OUT/table.txt" <<'PY'
import statistics, sys
lat = {}
for line in open(sys.argv[1]):
    tag, sep, rest = line.partition(": latency ")
    if sep:
        pair, mode = tag.split()
        lat.setdefault(pair, {})[mode] = [float(x) for x in rest.split()]
r50, r99, w50, w99 = [], [], [], []
for pair, m in lat.items():
    if "open" in m and "secure" in m and min(m["open"]) > 0 and min(m["secure"]) > 0:
        (o50, o99, ow50, ow99), (s50, s99, sw50, sw99) = m["open"], m["secure"]
        r50.append(s50 / o50)
        r99.append(s99 / o99)
        w50.append(sw50 / ow50)
        w99.append(sw99 / ow99)
        print(f"pair {pair}: secure/open latency p50 {r50[-1]:.2f}x ({s50:.0f} / {o50:.0f} us), "
              f"p99 {r99[-1]:.2f}x ({s99:.0f} / {o99:.0f} us) over the last 4096 periods; "
              f"over the run p50 {w50[-1]:.2f}x ({sw50:.0f} / {ow50:.0f} us), "
              f"p99 {w99[-1]:.2f}x ({sw99:.0f} / {ow99:.0f} us)")
    else:
        print(f"pair {pair}: incomplete (a run without a summary, latency or status lines)")
if r99:
    md = statistics.median
    print(f"secure/open latency over {len(r99)} pair(s): median p50 {md(r50):.2f}x, "
          f"median p99 {md(r99):.2f}x (last 4096 periods); over the run median p50 "
          f"{md(w50):.2f}x, median p99 {md(w99):.2f}x (target p99 <= 1.5x)")
PY
