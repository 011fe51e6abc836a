#!/usr/bin/env bash
# The chain a user with a lab robot runs (issue 29, item 6), on MuJoCo robots that are not the
# paper's, for each contact setting:
#   1. record, with the MuJoCo plant and the paper's model in the controller: an excitation run
#      (`live --reference excitation`, the arm's flat Fourier motion) and a tilting run
#      (`live --orbit-peak 0.04`: the robust trim, which holds tilting on MuJoCo);
#   2. identify from both (`identify exc tilt --params prior.toml --out robot.toml`; the prior
#      is what a ruler and a scale give: l, f, m_l, and the law a physical robot lands by,
#      `impact = "physical"`, whose restitution identify estimates from the tilts after the
#      landings: a pass-through, below 0, on MuJoCo);
#   3. plan: `plan orbit --params robot.toml --peak 0.018 --control-period 0.001 --json` (the
#      paper's gains; E_av refined for the loop sampled at 1 kHz with the robot's landings) ->
#      E_av and the simulated loop's period;
#   3b. (OPPOINT=1, the default) at the operating point: a tilting run of OP_S s on the plan
#      (`live --plan plan.json --orbit-peak PEAK`), identify again from the excitation and that
#      run, plan again (robot-first.toml and plan-first.json keep the first ones);
#   3c. (CAL=2, the default; 0 skips it) calibrate the plan on the robot: a run of the plain
#      law on the plan (CAL_S s, no link), then `plan orbit --peak PEAK --calibrate RUN...` with
#      every calibration run so far; CAL such rounds (plan-uncal.json keeps the plan before);
#   4. run live RUN_S s on MuJoCo over a 50 ms round trip (25 ms each way) with `--predict 0.05
#      --max-age 100 --params robot.toml --energy-avg E_av`: the plain adapted law, and with
#      `--orbit-peak 0.018`; for contrast the same two with the paper's law (robot.toml without
#      the impact key, the paper's E_av 19.963439703 J).
# The MuJoCo plant emulates no link (it refuses --delay), so the delay is a real one: live's
# plant command is bench/delay_plant.py, a delaying TCP proxy in front of the plant's port.
#
#   bench/mujoco_chain.sh [TABLE.md]          # default /tmp/mujoco_chain.md
#
# Env: TILTING (./target/release/tilting), OUT (runs/mujoco-chain-<UTC time>), ROBOTS ("a b"),
# OPPOINT (1; 0 skips step 3b), OP_S (60), LINK (real: step 4 over a delaying TCP proxy in real
# time; lockstep: the MuJoCo plant in lockstep emulates the same link, deterministic, and the
# recordings of steps 1 and 3b are made in lockstep too),
# CAL (2: rounds of step 3c; 0 skips it), CAL_S (40), CAL_LINK (0; 1: the calibration runs over
# step 4's link with its prediction),
# CONTACTS ("stiff mid moderate"), EXC_S (60), TILT_S (30), RUN_S (60), JOBS (1: chains one
# after another; 2 runs two chains side by side, which adds load and misses), RUNS (the live
# runs of step 4: LAW-plain|trim[-planstart], LAW physical or paper; -planstart: `live --plan
# plan.json`, the plant starts on the planned orbit's start state and the re-entry of
# --orbit-peak hands over there, instead of the paper's orbit start, the plant's default;
# default the physical law's two from the plan's start, the paper's law's two from its own),
# DWELL (0: remove the `contact_dwell` identify wrote, so that the controller answers the
# contact's flat reports at a landing as flat), REUSE (1: keep a chain's recordings when OUT has them, identify and plan again, and run only
# the RUNS without a summary.json yet; the figures of all RUNS are computed again).
# Needs: cargo build --release -p tilting; python3 -m pip install ./mujoco_plant.
set -uo pipefail
TABLE=${1:-/tmp/mujoco_chain.md}
HERE=$(cd "$(dirname "$0")" && pwd)
T=$(realpath "${TILTING:-./target/release/tilting}" 2>/dev/null) || T=""
OUT=${OUT:-runs/mujoco-chain-$(date -u +%Y%m%dT%H%M%SZ)}
ROBOTS=${ROBOTS:-a b}
CONTACTS=${CONTACTS:-stiff mid moderate}
EXC_S=${EXC_S:-60}
TILT_S=${TILT_S:-30}
RUN_S=${RUN_S:-60}
OP_S=${OP_S:-60}
JOBS=${JOBS:-1}
RUNS=${RUNS:-physical-plain-planstart physical-trim-planstart paper-plain paper-trim}
PAPER_EAV=19.963439703
PEAK=${PEAK:-0.018}
PEAK_FALLBACK=${PEAK_FALLBACK:-0.016}
# Extra flags of step 3's `plan orbit` (other gains, e.g. "--kd 10" for a 0.04 rad orbit; the
# live runs take the plan's gains with `--plan`).
PLAN_FLAGS=${PLAN_FLAGS:-}
if [ -z "$T" ] || ! [ -x "$T" ]; then
    echo "mujoco_chain: no tilting binary (build first: cargo build --release -p tilting)" >&2
    exit 2
fi
if ! python3 -c "import tilting_mujoco, mujoco" 2>/dev/null; then
    echo "mujoco_chain: no MuJoCo plant (python3 -m pip install ./mujoco_plant)" >&2
    exit 2
fi
mkdir -p "$OUT"
OUT=$(realpath "$OUT")

robot_toml() { # the true robot, which only the plant sees
    case $1 in
    # i_f: a 0.5 kg plate of 1 m (with 0.08, a 1 kg plate's, the paper's gains reach at most
    # 0.0169 rad for robot a and 0.0178 for b: `plan orbit --peak 0.018` refuses).
    a) printf 'm_f = 1.07\nm_l = 0.93\nl = 2.1\nl_c = 2.1\nf = 0.5\ni_f = 0.04\n' ;;
    b) printf 'm_f = 0.92\nm_l = 1.08\nl = 2.0\nl_c = 2.0\nf = 0.48\ni_f = 0.04\n' ;;
    *) return 1 ;;
    esac
}
contact_flags() {
    case $1 in
    stiff) echo "--preset stiff" ;;
    mid) echo "--preset stiff --solref 0.005,1 --solimp 0.95,0.99,0.001,0.5,2" ;;
    moderate) echo "--preset moderate" ;;
    *) return 1 ;;
    esac
}

# fail STEP LOG / say TEXT: use the caller's $d and $tag.
fail() { echo "mujoco_chain: $tag: FAILED at $1 (see $2)" >&2; echo "{\"failed\": \"$1\"}" >"$d/failed.json"; return 1; }
say() { echo "mujoco_chain: $tag: $*" >&2; }

# chain ROBOT CONTACT: one chain in $OUT/ROBOT-CONTACT; its figures in rows.jsonl there.
chain() {
    local robot=$1 contact=$2
    local d="$OUT/$robot-$contact" tag="$robot/$contact"
    local reuse=0
    if [ "${REUSE:-0}" = 1 ] && [ -s "$d/exc/run.mcap" ] && [ -s "$d/tilt/run.mcap" ]; then
        reuse=1
        rm -f "$d/failed.json"
    else
        rm -rf "$d"
        mkdir -p "$d"
    fi
    robot_toml "$robot" >"$d/true.toml" || { echo "$tag: FAILED at setup: unknown robot" >&2; return 1; }
    local cf
    cf=$(contact_flags "$contact") || { echo "$tag: FAILED at setup: unknown contact" >&2; return 1; }
    grep -E '^(m_l|l|f) ' "$d/true.toml" >"$d/prior.toml"
    # The law a physical robot lands by: identify keeps it and estimates its restitution.
    printf 'impact = "physical"\n' >>"$d/prior.toml"
    local plant="python3 -m tilting_mujoco $cf"
    # LINK=lockstep: every run of the chain in lockstep (recordings included), so that no
    # figure depends on the machine's load.
    local rec_plant="$plant"
    [ "${LINK:-real}" = lockstep ] && rec_plant="$plant --clock lockstep"

    if [ $reuse = 1 ]; then
        say "1. the recordings of $d kept (REUSE=1)"
    else
    say "1a. excitation run, ${EXC_S} s (live --reference excitation, paper's model in the controller)"
    "$T" live --plant-cmd "$rec_plant" --plant-params "$d/true.toml" --duration "$EXC_S" \
        --reference excitation --seed 0 --out "$d/exc" >"$d/exc.out" 2>&1 ||
        { fail "1a excitation run" "$d/exc.out"; return 1; }
    say "1b. tilting run, ${TILT_S} s (live --orbit-peak 0.04, paper's model)"
    "$T" live --plant-cmd "$rec_plant" --plant-params "$d/true.toml" --duration "$TILT_S" \
        --orbit-peak 0.04 --seed 0 --out "$d/tilt" >"$d/tilt.out" 2>&1
    [ -s "$d/tilt/run.mcap" ] && grep -q '"tilts": *[1-9]' "$d/tilt/summary.json" ||
        { fail "1b tilting run (no recording or no tilt)" "$d/tilt.out"; return 1; }
    fi

    say "2. identify (exc + tilt, prior l, f, m_l)"
    local note=""
    if ! "$T" identify "$d/exc/run.mcap" "$d/tilt/run.mcap" --params "$d/prior.toml" \
        --out "$d/robot.toml" --json >"$d/identify.json" 2>"$d/identify.err"; then
        say "2. identify refused with its defaults ($(tail -n1 "$d/identify.err")); again with --no-refine"
        note="identify --no-refine"
        if ! "$T" identify "$d/exc/run.mcap" "$d/tilt/run.mcap" --params "$d/prior.toml" \
            --no-refine --out "$d/robot.toml" --json >"$d/identify.json" 2>"$d/identify2.err"; then
            # The tilting run's windows across MuJoCo's landings (impulses no mode's equation
            # holds) pull b_v negative beyond its noise, and identify refuses. Then the arm from
            # the excitation alone, and the plate's mass weighed (in the prior), as a user would.
            say "2. refused again ($(tail -n1 "$d/identify2.err")); the excitation alone, m_f weighed"
            note="identify: excitation only, --no-refine, m_f weighed, i_f from the plate's size"
            grep -E '^m_f ' "$d/true.toml" >>"$d/prior.toml"
            "$T" identify "$d/exc/run.mcap" --params "$d/prior.toml" --no-refine \
                --out "$d/robot.toml" --json >"$d/identify.json" 2>"$d/identify3.err" ||
                { fail "2 identify" "$d/identify3.err"; return 1; }
            # The flat motion does not see the plate: its weighed m_f, and its inertia from its
            # size and mass (the true robot's i_f; a uniform plate's m_f (2f)^2 / 12 is 0.089
            # and 0.071 for robots a and b). Without it the plan is a point-mass plate's, and on
            # MuJoCo the loop ran an orbit of 0.063 rad for a plan of 0.018 (robot a, mid).
            sed -i "s/^m_f = .*/$(grep -E '^m_f ' "$d/true.toml")/" "$d/robot.toml"
            sed -i '/^i_f/d' "$d/robot.toml"
            grep -E '^i_f ' "$d/true.toml" >>"$d/robot.toml"
        fi
    fi
    if ! grep -q '^impact' "$d/robot.toml"; then
        printf '# appended by bench/mujoco_chain.sh: identify wrote no landing law\nimpact = "physical"\n' >>"$d/robot.toml"
        note="${note:+$note; }impact physical appended"
    elif ! grep -q '^impact = "physical"' "$d/robot.toml"; then
        # identify picks the law of the smallest residual; the chain is the physical law's.
        local chose
        chose=$(python3 -c '
import json, sys
l = json.load(open(sys.argv[1])).get("landing") or {}
print(l.get("best"), ", ".join("%s %.3f" % (w["law"], w["residual_rms"]) for w in l.get("laws", [])))' "$d/identify.json")
        say "2. identify chose the landing law ${chose%% *} (residuals ${chose#* }); set to physical"
        sed -i 's/^impact = .*/impact = "physical"/' "$d/robot.toml"
        note="${note:+$note; }identify chose ${chose%% *} (residual rms ${chose#* }), physical set"
    fi
    # The true i_f only while identify does not estimate the landing: once it does (a `landing`
    # object in its JSON) the plate's inertia is its estimate, as i_f or as a rotor on the
    # plate (j_m with n_g near 0: the same inertia of the plate).
    if ! grep -q '"landing"' "$d/identify.json" && ! grep -q '^i_f' "$d/robot.toml"; then
        grep '^i_f' "$d/true.toml" >>"$d/robot.toml"
        note="${note:+$note; }true i_f appended"
    fi
    # DWELL=0: the controller answers every flat report as flat (the robot file without the
    # contact's flat spell that identify measured), for contrast.
    if [ "${DWELL:-1}" = 0 ] && grep -q '^contact_dwell' "$d/robot.toml"; then
        sed -i '/^contact_dwell/d' "$d/robot.toml"
        note="${note:+$note; }contact_dwell removed (DWELL=0)"
    fi
    grep -Ev '^(impact|restitution|contact_dwell)' "$d/robot.toml" >"$d/robot-paper.toml"

    say "3. plan orbit --peak $PEAK (paper's gains)"
    local peak=$PEAK
    if ! "$T" plan orbit --params "$d/robot.toml" --peak "$peak" --control-period 0.001 $PLAN_FLAGS --json >"$d/plan.json" 2>"$d/plan.err"; then
        # The plate's inertia lowers the largest peak the paper's gains reach (0.0169 rad for
        # the paper's robot with i_f 0.08): then the chain goes on at PEAK_FALLBACK, said in
        # the notes, rather than with other gains.
        local most
        most=$(grep -o 'largest peak its family reaches is [0-9.]*' "$d/plan.err" | awk '{print $NF}')
        [ -n "$most" ] || { fail "3 plan orbit --peak $peak" "$d/plan.err"; return 1; }
        say "3. plan refused $peak rad (largest $most rad); planning $PEAK_FALLBACK rad instead"
        note="${note:+$note; }$peak refused (largest $most), planned $PEAK_FALLBACK"
        peak=$PEAK_FALLBACK
        "$T" plan orbit --params "$d/robot.toml" --peak "$peak" --control-period 0.001 $PLAN_FLAGS --json >"$d/plan.json" 2>"$d/plan.err" ||
            { fail "3 plan orbit --peak $peak" "$d/plan.err"; return 1; }
    fi
    # 3b. The landings at the planned orbit's own height (OPPOINT=1, the default): MuJoCo's
    # contact passes a larger share of a slow landing on into the next tilt (restitution -0.18
    # at 0.018 rad against -0.11 at 0.04), and the predictor over the 50 ms link runs the
    # landings of the robot file. A tilting run on the plan with the trim (which holds it),
    # identify again from the excitation and that run, plan again; if any step fails, the first
    # robot file and plan stay (said in the notes).
    if [ "${OPPOINT:-1}" = 1 ]; then
        cp "$d/robot.toml" "$d/robot-first.toml"
        if [ $reuse = 1 ] && [ -s "$d/op/run.mcap" ]; then
            say "3b. the operating point's recording kept (REUSE=1)"
        else
            say "3b. tilting run on the plan, ${OP_S} s (live --plan plan.json --orbit-peak $peak)"
            "$T" live --plant-cmd "$rec_plant" --plant-params "$d/true.toml" --params "$d/robot.toml" \
                --plan "$d/plan.json" --orbit-peak "$peak" --duration "$OP_S" --seed 0 \
                --out "$d/op" >"$d/op.out" 2>&1
        fi
        cp "$d/plan.json" "$d/plan-first.json"
        if [ -s "$d/op/run.mcap" ] &&
            "$T" identify "$d/exc/run.mcap" "$d/op/run.mcap" --params "$d/prior.toml" \
                --out "$d/robot-op.toml" --json >"$d/identify-op.json" 2>"$d/identify-op.err" &&
            grep -q '^impact = "physical"' "$d/robot-op.toml" &&
            "$T" plan orbit --params "$d/robot-op.toml" --peak "$peak" --control-period 0.001 \
                $PLAN_FLAGS --json >"$d/plan-op.json" 2>"$d/plan-op.err"; then
            local e0 e1
            e0=$(grep '^restitution' "$d/robot-first.toml" | awk '{print $3}')
            e1=$(grep '^restitution' "$d/robot-op.toml" | awk '{print $3}')
            say "3b. identified at the operating point: restitution ${e1:-0} (at 0.04 rad: ${e0:-0}); planned again"
            cp "$d/robot-op.toml" "$d/robot.toml"
            cp "$d/plan-op.json" "$d/plan.json"
            grep -Ev '^(impact|restitution|contact_dwell)' "$d/robot.toml" >"$d/robot-paper.toml"
            note="${note:+$note; }identified at the operating point (restitution ${e1:-0}, at 0.04 rad ${e0:-0})"
        else
            say "3b. the operating point's identification or plan failed (op.out, identify-op.err, plan-op.err): the first robot file and plan stay"
            note="${note:+$note; }operating-point identification failed, first robot kept"
        fi
    fi
    # 3c. Calibrate the plan on the robot: the rigid model's instant landing misses a small,
    # steady share of the orbit's energy balance (the contact rings for about 5 ms), which at
    # the 0.018 orbit moves the plain law's peak by 4-6 %. Each round runs the plain law on
    # the plan (no link: the link costs nothing on average once the landings are identified at
    # the operating point) and plans again with every calibration run so far.
    if [ "${CAL:-2}" -gt 0 ]; then
        cp "$d/plan.json" "$d/plan-uncal.json"
        local i cal_runs=()
        for i in $(seq 1 "${CAL:-2}"); do
            if [ $reuse = 1 ] && [ -s "$d/cal$i/run.mcap" ]; then
                say "3c. calibration run $i kept (REUSE=1)"
            else
                say "3c. calibration run $i: the plain law on the plan, ${CAL_S:-40} s"
                local cal_how=(--plant-cmd "$rec_plant" --seed 0)
                # CAL_LINK=1: over step 4's 50 ms link with its prediction, the conditions
                # the plan is run in (on a compliant contact the link moves the orbit by more
                # than the calibration corrects: mid contact, -16 % without, +8 % with).
                [ "${CAL_LINK:-0}" = 1 ] && mapfile -t cal_how < <(link_flags "$plant")
                "$T" live "${cal_how[@]}" --plant-params "$d/true.toml" --params "$d/robot.toml" \
                    --plan "$d/plan.json" --duration "${CAL_S:-40}" --out "$d/cal$i" >"$d/cal$i.out" 2>&1
            fi
            cal_runs+=("$d/cal$i")
            if "$T" plan orbit --params "$d/robot.toml" --peak "$peak" --control-period 0.001 \
                $PLAN_FLAGS --calibrate "${cal_runs[@]}" --json >"$d/plan-cal.json" 2>"$d/plan-cal.err"; then
                cp "$d/plan-cal.json" "$d/plan.json"
                say "3c. calibrated on $i run(s): $(python3 -c '
import json, sys
c = json.load(open(sys.argv[1]))["calibration"]
print("bias " + ", ".join("%+.2f %%" % (100 * r["bias"] / float(sys.argv[2])) for r in c["runs"]) +
      "; the model settled at %.6f rad" % c["model_peak"])' "$d/plan.json" "$peak")"
            else
                say "3c. calibration failed (plan-cal.err): the plan before it stays"
                note="${note:+$note; }calibration round $i failed"
                break
            fi
        done
        note="${note:+$note; }calibrated on the robot (${CAL:-2} rounds)"
    fi
    local e_av period
    read -r e_av period < <(python3 -c '
import json, sys
p = json.load(open(sys.argv[1]))
s = p.get("calibration") or p.get("settled") or p["solutions"][0]
print(repr(p["energy_avg_adaptation"]), repr(s["period"]), file=open(sys.argv[2], "w"))
print(repr(p["energy_avg_adaptation"]), repr(s["period"]))' "$d/plan.json" "$d/plan.txt") ||
        { fail "3 plan orbit (reading its JSON)" "$d/plan.json"; return 1; }
    say "3. E_av $e_av J, period $period s"
    printf '%s\n' "$note" >"$d/note.txt"
    runs_only "$robot" "$contact"
}

# link_flags PLANT: live's flags for the 50 ms round trip of step 4, one per line (read them
# with `mapfile -t`: the plant command is one flag value with spaces).
link_flags() {
    local cmd="python3 $HERE/delay_plant.py $1 --watchdog 100"
    # LINK=lockstep: the link emulated by the MuJoCo plant in lockstep (docs/mujoco.md): the
    # same 25 ms each way, deterministic, whatever the machine's load.
    [ "${LINK:-real}" = lockstep ] && cmd="$1 --clock lockstep"
    printf '%s\n' --plant-cmd "$cmd" --delay 0.025 --predict 0.05 --max-age 100 --seed 0
}

# runs_only ROBOT CONTACT: step 4 and 5 of a chain whose robot.toml and plan.json exist.
runs_only() {
    local robot=$1 contact=$2
    local d="$OUT/$robot-$contact" tag="$robot/$contact"
    local cf plant note e_av period peak
    cf=$(contact_flags "$contact")
    plant="python3 -m tilting_mujoco $cf"
    note=$(cat "$d/note.txt" 2>/dev/null)
    read -r e_av period peak < <(python3 -c '
import json, sys
p = json.load(open(sys.argv[1]))
s = p["solutions"][0]
# A calibrated plan settles the model below the wanted peak; the period of the robot at the
# peak is that of the model loop at the peak itself.
period = (p.get("calibration") or p.get("settled") or s)["period"]
print(repr(p["energy_avg_adaptation"]), repr(period), round(s["max_tilt"], 6))' "$d/plan.json") ||
        { fail "4 (reading plan.json)" "$d/plan.json"; return 1; }
    local link
    mapfile -t link < <(link_flags "$plant")
    link+=(--plant-params "$d/true.toml" --duration "$RUN_S")
    local run law trim start rest
    rm -f "$d/rows.jsonl"
    for run in $RUNS; do
        law=${run%%-*} rest=${run#*-} trim=${rest%%-*} start=paper
        [ "$run" != "${run%-planstart}" ] && start=plan
        local args=("${link[@]}")
        if [ "${REUSE:-0}" = 1 ] && [ -s "$d/$run/summary.json" ]; then
            say "4. $run kept (REUSE=1)"
        else
        if [ "$law" = physical ] && [ "$start" = plan ]; then
            # The plan's law and orbit start (`live --plan`: E_av, and the plant starts on the
            # planned orbit, where --orbit-peak's re-entry also hands over).
            args+=(--params "$d/robot.toml" --plan "$d/plan.json")
        elif [ "$law" = physical ]; then
            args+=(--params "$d/robot.toml" --energy-avg "$e_av")
        else
            args+=(--params "$d/robot-paper.toml" --energy-avg "$PAPER_EAV")
        fi
        [ "$trim" = trim ] && args+=(--orbit-peak "$peak")
        local what="plain adapted law"
        [ "$trim" = trim ] && what="--orbit-peak $peak"
        say "4. live ${RUN_S} s over a 50 ms round trip, $law law, $what, from the $start orbit's start"
        "$T" live "${args[@]}" --out "$d/$run" >"$d/$run.out" 2>&1
        [ -s "$d/$run/summary.json" ] || { fail "4 live $run" "$d/$run.out"; return 1; }
        fi
        python3 "$HERE/mujoco_figures.py" "$d/$run" "$peak" "$period" | python3 -c '
import json, sys
f = json.load(sys.stdin)
f.update(robot=sys.argv[1], contact=sys.argv[2], law=sys.argv[3], trim=sys.argv[4],
         e_av=float(sys.argv[5]), plan_period=float(sys.argv[6]), note=sys.argv[7],
         peak=float(sys.argv[8]), start=sys.argv[9])
print(json.dumps(f))' "$robot" "$contact" "$law" "$trim" \
            "$([ "$law" = physical ] && echo "$e_av" || echo "$PAPER_EAV")" "$period" "$note" "$peak" "$start" \
            >>"$d/rows.jsonl" || { fail "5 figures of $run" "$d/$run/summary.json"; return 1; }
        say "5. $run: $(tail -n1 "$d/rows.jsonl" | python3 -c '
import json, sys
f = json.load(sys.stdin)
g = lambda v: "-" if v is None else f"{v:+.1f} %"
print("%s tilts, %s alternating, worst %s, mean %s, period %s, unanswered %s" % (f["tilts"],
      f["alternating"], g(f["worst"]), g(f["mean"]), g(f["period"]), f["unanswered"]))')"
    done
    say "done"
}

pids=()
for robot in $ROBOTS; do
    for contact in $CONTACTS; do
        if [ "$JOBS" -le 1 ]; then
            chain "$robot" "$contact"
        else
            while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do sleep 1; done
            chain "$robot" "$contact" &
            pids+=($!)
        fi
    done
done
wait

python3 - "$OUT" "$TABLE" "$ROBOTS" "$CONTACTS" <<'PY'
import json, os, sys
out, table, robots, contacts = sys.argv[1], sys.argv[2], sys.argv[3].split(), sys.argv[4].split()
g = lambda v: "-" if v is None else f"{v:+.1f}"
head = ("| robot | contact | law | --orbit-peak | start | plan peak (rad), period (s) | E_av (J) | tilts | alternating | worst after 10th (%) "
        "| mean (%) | period (%) | settled at tilt | worst after 40th (%) | unanswered | torque age p99 "
        "| notes |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n")
rows = []
for r in robots:
    for c in contacts:
        d = f"{out}/{r}-{c}"
        if os.path.exists(f"{d}/failed.json"):
            rows.append(f"| {r} | {c} | failed at {json.load(open(f'{d}/failed.json'))['failed']} "
                        "| | | | | | | | | | | | | | |")
        if not os.path.exists(f"{d}/rows.jsonl"):
            continue
        for line in open(f"{d}/rows.jsonl"):
            f = json.loads(line)
            trim = "yes" if f["trim"] == "trim" else "no"
            fault = f", fault {f['fault']}" if f["fault"] else ""
            rows.append(
                f"| {r} | {c} | {f['law']} | {trim} | {f.get('start', 'paper')} | {f['peak']}, {f['plan_period']:.4f} | {f['e_av']:.6f} | {f['tilts']} | {f['alternating']} "
                f"| {g(f['worst'])} | {g(f['mean'])} | {g(f['period'])} | {f['settled'] or 'never'} "
                f"| {g(f['worst40'])} | {f['unanswered']} of {f['periods']} | {f['age_p99']:.0f}{fault} "
                f"| {f['note']} |")
text = head + "\n".join(rows) + "\n"
open(table, "w").write(text)
print(text)
PY
echo "mujoco_chain: table in $TABLE, runs in $OUT" >&2
