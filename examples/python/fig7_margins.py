"""Fig. 7 and a margins map, drawn from Python with the `tilting` package (pip install ./python)
and matplotlib.

Fig. 7: the paper's unstable orbit (K_P = 100, K_D = 14.14) started 1e-3 rad/s above and below
its exact beta_dot0 drifts away without adaptation (k = 0) and is held by the energy adaptation
(k = 500, E_av of the orbit). The margins map: which constant delays and losses the stabilised
orbit survives, with and without prediction.

    python3 examples/python/fig7_margins.py --out figs/   # writes fig7.png, margins.png
"""

import argparse
import os
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tilting  # noqa: E402


def fig7(out, duration):
    kp, kd = 100.0, 14.14
    o = tilting.plan.orbit(kp=kp, kd=kd).solutions[0]  # the smallest tilt: the paper's orbit
    runs = [
        ("k = 0, -1e-3 rad/s", 0.0, -1e-3, "tab:blue"),
        ("k = 500, +1e-3 rad/s", 500.0, 1e-3, "tab:green"),
        ("k = 0, +1e-3 rad/s", 0.0, 1e-3, "tab:red"),
    ]
    fig, ax = plt.subplots(figsize=(9, 4))
    for name, k, d, color in runs:
        r = tilting.simulate(
            duration=duration, kp=kp, kd=kd, k=k, energy_avg=o.energy_avg, mode="left",
            x0=[0.0, np.pi / 2 + o.beta0, 0.0, o.beta_dot0 + d],
        )
        label = name + (f" ({r.fault.split(':')[0]})" if r.fault else "")
        ax.plot(r.t, r.x[:, 0], color=color, lw=0.8, label=label)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("alpha (rad)")
    ax.set_title(f"Fig. 7: the orbit of K_P = {kp}, K_D = {kd} (E_av = {o.energy_avg:.4f} J)")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig7.png"), dpi=120)


def margins(out, tilts):
    m = tilting.plan.margins(tilts=tilts)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, grid, title in ((axes[0], m.survived, "plain"), (axes[1], m.survived_predict, "--predict auto")):
        ax.imshow(grid, cmap="RdYlGn", vmin=0, vmax=1, origin="lower", aspect="auto")
        ax.set_xticks(range(len(m.losses)), [f"{v:g}" for v in m.losses])
        ax.set_yticks(range(len(m.delays)), [f"{1000 * v:g}" for v in m.delays])
        ax.set_xlabel("loss of each direction")
        ax.set_title(f"survives ({title})")
    axes[0].set_ylabel("total delay (ms)")
    fig.suptitle(f"What the stabilised orbit survives at {m.report['rate']:g} Hz ({tilts} tilts)")
    fig.tight_layout()
    fig.savefig(os.path.join(out, "margins.png"), dpi=120)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", default=".")
    p.add_argument("--duration", type=float, default=15.0, help="Fig. 7 run length (s)")
    p.add_argument("--tilts", type=int, default=200, help="tilts per margins point")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    t0 = time.perf_counter()
    fig7(a.out, a.duration)
    t1 = time.perf_counter()
    margins(a.out, a.tilts)
    t2 = time.perf_counter()
    print(f"fig7.png in {t1 - t0:.1f} s, margins.png in {t2 - t1:.1f} s ({a.out})")
