#!/usr/bin/env python3
"""Figures of one live run of bench/mujoco_chain.sh, from its summary.json (the plant's
summary: tilt_peaks as [t, alpha] pairs, torque ages, losses). Prints one JSON object.

    mujoco_figures.py RUN_DIR PEAK PERIOD

Definitions (as bench/headline.sh and cli/tests/cli/headline_cli.rs): a tilt is a lift-off whose
peak |alpha| exceeds 0.01 rad; `alternating` counts the tilts whose sign differs from the tilt
before (the first one counts); after the first 10 tilts: `worst` the largest |peak| error
relative to PEAK (signed, %), `mean` the mean |peak| relative to PEAK, minus 1 (%);
`period` the mean time from a tilt to the next tilt of the same sign, relative to PERIOD (%),
over the same tilts; diagnostics `settled` (the tilt from which every peak is within 10 %)
and `worst40` (the worst error after the 40th tilt); `low` the lift-offs below 0.01 rad; `unanswered` the states whose
torque was never applied (lost, or older than --max-age on arrival), `late` the torques that
arrived after their state's deadline (with a 50 ms round trip every torque does, so the
deadline-miss count of the plant is every period), `age_p99` the torques' age in periods.
"""
import json
import sys


def figures(run_dir, peak, period):
    s = json.load(open(f"{run_dir}/summary.json"))
    p = s.get("plant") or {}
    every = [(t, a) for t, a in p.get("tilt_peaks", [])]
    tilts = [(t, a) for t, a in every if abs(a) > 0.01]
    alt = sum(1 for i, (_, a) in enumerate(tilts) if i == 0 or (a > 0) != (tilts[i - 1][1] > 0))
    after = tilts[10:]
    errs = [(abs(a) - peak) / peak for _, a in after]
    worst = max(errs, key=abs) if errs else None
    mean = (sum(abs(a) for _, a in after) / len(after) - peak) / peak if after else None
    gaps = [tilts[i + 2][0] - tilts[i][0] for i in range(10, len(tilts) - 2)]
    per = (sum(gaps) / len(gaps) - period) / period if gaps else None
    # Diagnostics (not criteria): how long the start transient lasts. `settled` is the 1-based
    # tilt from which every later peak is within 10 % of PEAK (None: never), `worst40` the worst
    # error after the 40th tilt.
    all_errs = [(abs(a) - peak) / peak for _, a in tilts]
    settled = None
    for i in range(len(all_errs), 0, -1):
        if abs(all_errs[i - 1]) >= 0.10:
            settled = i + 1 if i < len(all_errs) else None
            break
    else:
        settled = 1 if all_errs else None
    w40 = max(all_errs[40:], key=abs) if len(all_errs) > 40 else None
    # The last tilt, for "how long did it last".
    last_t = tilts[-1][0] if tilts else None
    ages = p.get("age_periods") or {}
    return {
        "run": run_dir,
        "result": s.get("result"),
        "orbit": (s.get("orbit") or {}).get("state"),
        "fault": p.get("fault"),
        "tilts": len(tilts),
        "alternating": alt,
        "worst": None if worst is None else 100 * worst,
        "mean": None if mean is None else 100 * mean,
        "period": None if per is None else 100 * per,
        "low": len(every) - len(tilts),
        "settled": settled,
        "worst40": None if w40 is None else 100 * w40,
        "last_tilt_t": last_t,
        "unanswered": p.get("torques_lost"),
        "late": p.get("torques_late"),
        "deadline_misses": p.get("deadline_misses"),
        "age_p99": ages.get("p99"),
        "age_max": ages.get("max"),
        "watchdog_trips": p.get("watchdog_trips"),
        "safe_periods": p.get("safe_periods"),
        "periods": p.get("steps"),
    }


if __name__ == "__main__":
    d, peak, period = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    print(json.dumps(figures(d, peak, period)))
