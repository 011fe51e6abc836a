#!/usr/bin/env bash
# CPU starvation: `tilting live` (open) beside BUSY busy loops (default 6, on our 2 cores),
# without and with `--realtime` (the plant and the controller under SCHED_FIFO 20), PAIRS
# interleaved pairs (without first, then with first, ...), SECONDS each. Per run it prints the
# deadline misses (share of the run's periods), tilts, the orbit verdict, the loop latency p99
# over the plant's last 4096 periods, the largest overrun, whether the LOOP LATE alarm was
# raised, and the exit code; then the ratio of misses with/without per pair.
#
#   bench/starve.sh            # 30 s each, 2 pairs, 6 busy loops (4 min in all)
#   bench/starve.sh 60 1 4     # SECONDS PAIRS BUSY
#
# `--realtime` needs root, CAP_SYS_NICE or `ulimit -r 20`; without it the "with" runs fail at
# once and say so. Env: TILTING (default ./target/release/tilting), STARVE_OUT (default
# runs/starve-<UTC time>). Build first: cargo build --release --workspace --bins
set -uo pipefail
S=${1:-30}
PAIRS=${2:-2}
BUSY=${3:-6}
for v in "$S" "$PAIRS" "$BUSY"; do
    if ! [[ "$v" =~ ^[0-9]+$ ]]; then
        echo "usage: bench/starve.sh [SECONDS >= 10] [PAIRS >= 1] [BUSY >= 0]" >&2
        exit 2
    fi
done
if [ "$S" -lt 10 ] || [ "$PAIRS" -lt 1 ]; then
    echo "usage: bench/starve.sh [SECONDS >= 10] [PAIRS >= 1] [BUSY >= 0]" >&2
    exit 2
fi
T=${TILTING:-./target/release/tilting}
if ! [ -x "$T" ]; then
    echo "starve: no $T (build first: cargo build --release --workspace --bins)" >&2
    exit 2
fi
OUT=${STARVE_OUT:-runs/starve-$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$OUT"
echo "starve: $BUSY busy loops, $S s per run, $PAIRS pairs, $(nproc) CPUs; output in $OUT"

BUSY_PIDS=()
stop_busy() {
    [ ${#BUSY_PIDS[@]} -gt 0 ] && kill "${BUSY_PIDS[@]}" 2>/dev/null
    wait "${BUSY_PIDS[@]}" 2>/dev/null
    BUSY_PIDS=()
}
trap stop_busy EXIT

# run NAME [FLAGS...]: one run beside the busy loops; prints its row, echoes its misses.
run() {
    local name=$1
    shift
    local dir="$OUT/$name"
    for _ in $(seq "$BUSY"); do
        (while :; do :; done) &
        BUSY_PIDS+=($!)
    done
    "$T" live --duration "$S" --out "$dir" "$@" >"$dir.stdout" 2>"$dir.stderr"
    local rc=$?
    stop_busy
    python3 - "$dir" "$rc" "$name" <<'PY'
import json, sys
d, rc, name = sys.argv[1:4]
try:
    s = json.load(open(d + "/summary.json"))
except OSError as e:
    print(f"{name:>10}: exit {rc}, no summary ({e}); see {d}.stderr")
    sys.exit(0)
p = s.get("plant") or {}
o = s.get("orbit") or {}
steps = max(p.get("steps", 0), 1)
late = "yes" if "LOOP LATE" in open(d + ".stderr").read() else "no"
print(f"{name:>10}: misses {p.get('deadline_misses', 0):6d} ({100 * p.get('deadline_misses', 0) / steps:5.1f} %), "
      f"tilts {p.get('tilts', 0):4d}, orbit {o.get('state', '?'):5s}, latency p99 "
      f"{(p.get('latency_us') or {}).get('p99', float('nan')):8.0f} us, max overrun "
      f"{p.get('max_overrun_us', float('nan')):8.0f} us, LOOP LATE alarm {late}, exit {rc}")
with open(d + ".misses", "w") as f:
    f.write(str(p.get("deadline_misses", 0)))
PY
}

for i in $(seq "$PAIRS"); do
    if [ $((i % 2)) -eq 1 ]; then
        run "$i-without"
        run "$i-with" --realtime
    else
        run "$i-with" --realtime
        run "$i-without"
    fi
    a=$(cat "$OUT/$i-without.misses" 2>/dev/null || echo 0)
    b=$(cat "$OUT/$i-with.misses" 2>/dev/null || echo 0)
    python3 -c "import sys; a,b=int(sys.argv[1]),int(sys.argv[2]); print(f'pair {sys.argv[3]}: misses with/without --realtime {b}/{a} = {b/max(a,1):.4f}')" "$a" "$b" "$i"
done
