#!/usr/bin/env bash
# The headline chain (docs/guide/real-robot.md, "The same chain measured as hardware measures") over noise
# seeds and robots: for each robot and each seed 0 .. SEEDS-1 it runs the README's commands
# with `--seed SEED` on every `simulate` (the README's single run is seed 0, the default):
# a 300 s flat excitation and a 30 s orbit recorded with `--measure angles`, 1 mrad of noise
# and a 4,096-count encoder; `identify` on both (`--window 2 --half-window 0.05`); `plan
# orbit --k 500`; then 100 s of the identified model on the true robot over 25 ms each way with
# `--predict 0.05 --max-age 60`, with `--orbit-peak <planned peak>` and, for comparison,
# without it. Robots: `readme` is the README's `robot.toml` (m_f 0.85, m_l 1.1, l_c 1.8, i_l
# 0.08, j_m 0.02, n_g 0.8, b_v 0.03, tau_c 0.05), `second` the README's second robot (m_f 1.15,
# m_l 0.9, l_c 1.9, i_l 0.05, j_m 0.01, n_g 1.2, b_v 0.05, tau_c 0.03); the prior holds only
# the weighed m_l.
#
# Per run it prints the identified parameters' errors against the true robot (m_f, l_c, J =
# pi3+pi5 = m_l l_c^2 + i_l + n_g^2 j_m the arm's inertia about the joint, tau_c, b_v and b_v's
# standard error relative to the true b_v; whether the output-error refinement of b_v
# converged), the planned E_av (J) and peak (rad), and of the 100 s runs the figures
# cli/tests/cli/headline_cli.rs asserts, with its definitions: a tilt is a lift-off whose peak
# |alpha| exceeds 0.01 rad (`tilt_peaks` of `simulate --json`); whether every tilt alternates
# in sign; after the first 10 tilts, the worst |peak| error and the mean |peak| error relative
# to the planned peak; the last tilt more than 10 % off (1-based: "5" is the 5th tilt; "-"
# none); the lift-offs below 0.01 rad; and a fault, if any. E_av and the peak go to `simulate`
# at full precision from `plan orbit --json`, as the test passes them (the README's line types
# the printed 0.0432: single peaks move by a few % with such a change, the mean does not).
#
#   bench/headline.sh                 # both robots, seeds 0..3: 8 runs (about 20 s each here)
#   bench/headline.sh 1 readme        # the README's robot, seed 0 only
#   bench/headline.sh 4 second        # the second robot, seeds 0..3
#
# Env: TILTING (default ./target/release/tilting), HEADLINE_OUT (default
# runs/headline-<UTC time>). Build first: cargo build --release -p tilting
set -uo pipefail
SEEDS=${1:-4}
ROBOTS=${2:-both}
if ! [[ "$SEEDS" =~ ^[0-9]+$ ]] || [ "$SEEDS" -lt 1 ] ||
    ! [[ "$ROBOTS" =~ ^(readme|second|both)$ ]]; then
    echo "usage: bench/headline.sh [SEEDS >= 1] [readme|second|both]" >&2
    exit 2
fi
T=${TILTING:-./target/release/tilting}
if ! [ -x "$T" ]; then
    echo "headline: no $T (build first: cargo build --release -p tilting)" >&2
    exit 2
fi
OUT=${HEADLINE_OUT:-runs/headline-$(date -u +%Y%m%dT%H%M%SZ)}
mkdir -p "$OUT"
: >"$OUT/table.txt"

robot_toml() {
    case $1 in
    readme) printf 'm_f = 0.85\nm_l = 1.1\nl_c = 1.8\ni_l = 0.08\nj_m = 0.02\nn_g = 0.8\nb_v = 0.03\ntau_c = 0.05\n' ;;
    second) printf 'm_f = 1.15\nm_l = 0.9\nl_c = 1.9\ni_l = 0.05\nj_m = 0.01\nn_g = 1.2\nb_v = 0.05\ntau_c = 0.03\n' ;;
    esac
}
[ "$ROBOTS" = both ] && ROBOTS="readme second"

# step DIR NAME CMD...: runs CMD with its stdout in DIR/NAME.json (or .out) and its stderr in
# DIR/NAME.err; returns its exit status.
step() {
    local dir=$1 name=$2
    shift 2
    "$@" >"$dir/$name.json" 2>"$dir/$name.err"
}

# run ROBOT SEED: one chain, its line appended to table.txt.
run() {
    local robot=$1 seed=$2
    local d="$OUT/$robot-seed$seed"
    mkdir -p "$d"
    robot_toml "$robot" >"$d/robot.toml"
    grep '^m_l' "$d/robot.toml" >"$d/prior.toml"
    local n=(--measure angles --noise-alpha 0.001 --noise-beta 0.001 --encoder-counts 4096
        --seed "$seed")
    local t0=$SECONDS failed=""
    echo "headline: $robot, seed $seed -> $d" >&2
    step "$d" exc "$T" simulate --plant-params "$d/robot.toml" --control-period 0.001 \
        --duration 300 --reference excitation "${n[@]}" --record "$d/exc.mcap" || failed=exc
    [ -z "$failed" ] && { step "$d" orbit "$T" simulate --plant-params "$d/robot.toml" \
        --control-period 0.001 --duration 30 --orbit-peak 0.04 "${n[@]}" \
        --record "$d/orbit.mcap" || failed=orbit; }
    [ -z "$failed" ] && { step "$d" identify "$T" identify "$d/exc.mcap" "$d/orbit.mcap" \
        --params "$d/prior.toml" --window 2 --half-window 0.05 \
        --out "$d/identified.toml" --json || failed=identify; }
    [ -z "$failed" ] && { step "$d" plan "$T" plan orbit --params "$d/identified.toml" \
        --k 500 --json || failed=plan; }
    local e_av="" peak=""
    if [ -z "$failed" ]; then
        read -r e_av peak < <(python3 - "$d/plan.json" <<'PY'
import json, sys
def walk(v, key):
    if isinstance(v, dict):
        if isinstance(v.get(key), (int, float)):
            return v[key]
        return next((x for x in (walk(w, key) for w in v.values()) if x is not None), None)
    if isinstance(v, list):
        return next((x for x in (walk(w, key) for w in v) if x is not None), None)
    return None
p = json.load(open(sys.argv[1]))
print(repr(walk(p, "energy_avg_adaptation")), repr(walk(p, "max_tilt")))
PY
        )
        [ -n "$peak" ] && [ "$peak" != None ] || failed=plan
    fi
    local live=(simulate --params "$d/identified.toml" --plant-params "$d/robot.toml" --k 500
        --energy-avg "$e_av" --control-period 0.001 --duration 100 --delay 0.025 --predict 0.05
        --max-age 60 "${n[@]}" --json)
    [ -z "$failed" ] && { step "$d" trim "$T" "${live[@]}" --orbit-peak "$peak" ||
        failed=simulate; }
    [ -z "$failed" ] && { step "$d" notrim "$T" "${live[@]}" || failed="simulate (no trim)"; }
    python3 - "$robot" "$seed" "$d" "$((SECONDS - t0))" "$failed" "$e_av" "$peak" \
        >>"$OUT/table.txt" <<'PY'
import json, sys
robot, seed, d, secs, failed, e_av, peak = sys.argv[1:]
tag = f"{robot:6} seed {seed}"
if failed:
    name = {"simulate": "trim", "simulate (no trim)": "notrim"}.get(failed, failed)
    err = open(f"{d}/{name}.err", errors="replace")
    last = [l.strip() for l in err if l.strip()][-1:] or ["(no message)"]
    print(f"{tag}: the chain failed at {failed}: {last[0]}")
    sys.exit()
true = {}
for line in open(f"{d}/robot.toml"):
    k, v = line.split("=")
    true[k.strip()] = float(v)
ident = json.load(open(f"{d}/identify.json"))
p = ident["params"]
base = {e["name"]: e for e in ident["base"]}
def pct(got, want):
    return f"{100 * (got - want) / want:+.2f} %"
lc = p.get("l_c") if p.get("l_c") is not None else p["l"]
j_true = true["m_l"] * true["l_c"] ** 2 + true["i_l"] + true["n_g"] ** 2 * true["j_m"]
if "pi3+pi5" in base and base["pi3+pi5"]["value"] is not None:
    j_got = base["pi3+pi5"]["value"]
else:
    j_got = p["m_l"] * lc ** 2 + p.get("i_l", 0.0) + p.get("n_g", 1.0) ** 2 * p.get("j_m", 0.0)
r = ident.get("refinement")
if r is None:
    refined = "no refinement"
elif r["converged"]:
    refined = f"refinement converged ({r['iterations']} iterations)"
else:
    refined = (f"refinement NOT converged ({r['iterations']} iterations; its b_v "
               f"{pct(r['value'][2], true['b_v'])}: the least squares' b_v and tau_c kept)")
se = base["pi6"]["std_error"]
se = f"{100 * se / true['b_v']:.1f} %" if se is not None else "-"
print(f"{tag}: identify m_f {pct(p['m_f'], true['m_f'])}, l_c {pct(lc, true['l_c'])}, "
      f"J {pct(j_got, j_true)}, tau_c {pct(p['tau_c'], true['tau_c'])}, "
      f"b_v {pct(p['b_v'], true['b_v'])} (standard error {se}); {refined}")
e_av, peak = float(e_av), float(peak)
print(f"{tag}: plan E_av {e_av:.9f} J, peak {peak:.6f} rad")
# The figures of cli/tests/cli/headline_cli.rs.
def figures(name):
    run = json.load(open(f"{d}/{name}.json"))
    every = [t["alpha"] for t in run["tilt_peaks"]]
    tilts = [a for a in every if abs(a) > 0.01]
    errs = [(abs(a) - peak) / peak for a in tilts]
    after = errs[10:]
    worst = max(after, key=abs) if after else float("nan")
    mean = (sum(abs(a) for a in tilts[10:]) / len(after) - peak) / peak if after else float("nan")
    outside = [i + 1 for i, e in enumerate(errs) if abs(e) >= 0.10]
    return {
        "fault": run.get("fault"),
        "tilts": len(tilts),
        "alternate": all((x > 0) != (y > 0) for x, y in zip(tilts, tilts[1:])),
        "worst": worst,
        "mean": mean,
        "last_outside": outside[-1] if outside else "-",
        "low": len(every) - len(tilts),
    }
t, n = figures("trim"), figures("notrim")
fault = f", FAULT {t['fault']}" if t["fault"] is not None else ""
print(f"{tag}: 100 s with --orbit-peak: {t['tilts']} tilts, alternate {t['alternate']}, "
      f"after the 10th worst {100 * t['worst']:+.1f} % mean {100 * t['mean']:+.1f} %, "
      f"last outside 10 % {t['last_outside']}, lift-offs below 0.01 rad {t['low']}{fault}")
fault = f", FAULT {n['fault']}" if n["fault"] is not None else ""
print(f"{tag}: 100 s without --orbit-peak: {n['tilts']} tilts, after the 10th worst "
      f"{100 * n['worst']:+.1f} % mean {100 * n['mean']:+.1f} %, last outside 10 % "
      f"{n['last_outside']}, lift-offs below 0.01 rad {n['low']}{fault}")
print(f"{tag}: {secs} s")
PY
    grep "^$robot *seed $seed:" "$OUT/table.txt" >&2
}

for robot in $ROBOTS; do
    for seed in $(seq 0 $((SEEDS - 1))); do
        run "$robot" "$seed"
    done
done
echo "headline: table in $OUT/table.txt" >&2
cat "$OUT/table.txt"
