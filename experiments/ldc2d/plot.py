"""Figs. 6 and 7: 2D lid-driven cavity at Re = 100. Top: velocity magnitude of the particles at
t_end, one panel per method. Bottom: centreline profiles u(y) at x = 0.5 and v(x) at y = 0.5 of each
method (SPH interpolation averaged over the last frames, analysis.py) against Ghia et al. (1982).

Fig. 6 uses the runs at figures.fig6's dx (paper: 0.02), Fig. 7 those at figures.fig7's (0.01).
Reads results/<profile>/ldc2d/<method>_dx<dx>/{traj.h5,profiles.npz} (re-evaluating
the runs first, so a changed `analysis` setting takes effect); writes results/<profile>/<fig>/
<fig>.{png,pdf} and <fig>/metrics.csv (the metrics rows of that dx); with --gif PATH only an animation
of one method's run of that figure (--method, default tvf; lab.animate).

    python experiments/ldc2d/plot.py --fig fig6 --profile smoke [--results results/smoke] [--gif fig6.gif]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from sph.cases import ldc_reference  # noqa: E402
from lab import animate, io  # noqa: E402
from sph.state import FLUID, MOVING_WALL  # noqa: E402
try:  # noqa: E402
    from . import analysis
    from . import run as R
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import analysis
    import run as R
    import settings as S

COLORS = {"sph": "tab:blue", "tvf": "tab:orange", "riemann": "tab:green"}
LABELS = {"sph": "SPH", "tvf": "SPH + TVF", "riemann": "Riemann SPH"}


def plot(exp: "S.Experiment", results, fig_name: str) -> Path:
    if fig_name not in exp.figures:
        raise SystemExit(f"profile has no {fig_name} (figures: {list(exp.figures)})")
    dx = float(exp.figures[fig_name])
    rows = []
    for m in exp.methods:
        traj = S.run_dir(results, m.name, dx) / "traj.h5"
        if not io.trajectory_status(traj)["complete"]:
            raise SystemExit(f"{fig_name}: run {m.name} {S.dx_tag(dx)} is not complete ({traj}); run "
                             f"experiments/ldc2d/run.py --fig {fig_name} first")
        rows.append(R.evaluate(exp, m.name, dx, results))  # cached beside the run
    out = Path(results) / fig_name
    out.mkdir(parents=True, exist_ok=True)

    n = len(exp.methods)
    fig = plt.figure(figsize=(4.0 * n, 8.2), constrained_layout=True)
    gs = fig.add_gridspec(2, 2 * n)
    field_axes = [fig.add_subplot(gs[0, 2 * i:2 * i + 2]) for i in range(n)]
    ax_u = fig.add_subplot(gs[1, :n])
    ax_v = fig.add_subplot(gs[1, n:])
    vmax = exp.lid_velocity
    scatters = []
    for ax, m, row in zip(field_axes, exp.methods, rows):
        tr = io.read_trajectory(S.run_dir(results, m.name, dx) / "traj.h5")
        meta_off = analysis.Interpolator(S.run_dir(results, m.name, dx), exp.analysis).offset
        r = tr["position"][-1] - meta_off
        speed = np.linalg.norm(tr["velocity"][-1], axis=1)
        tag = tr["particle_type"]
        fl = tag == FLUID
        walls = ax.scatter(r[~fl, 0], r[~fl, 1], s=1, marker="s", linewidths=0,
                           c=np.where(tag[~fl] == MOVING_WALL, "0.35", "0.75"))
        sc = ax.scatter(r[fl, 0], r[fl, 1], c=speed[fl], s=1, marker="s", linewidths=0, cmap="viridis",
                        vmin=0.0, vmax=vmax)
        scatters.append((ax, dx, 1.0 + 2 * meta_off, (walls, sc)))
        ax.set(xlim=(-meta_off, 1 + meta_off), ylim=(-meta_off, 1 + meta_off), aspect="equal", xlabel="x",
               ylabel="y", title=f"{LABELS.get(m.name, m.name)}, t = {tr['time'][-1]:.3g}")
        fig.colorbar(sc, ax=ax, label="|u|", shrink=0.85)

    yg, ug = ldc_reference.ghia("u", exp.ghia_re)
    xg, vg = ldc_reference.ghia("v", exp.ghia_re)
    ax_u.plot(ug, yg, "ko", ms=5, label=f"Ghia et al. (1982), Re = {exp.ghia_re}")
    ax_v.plot(xg, vg, "ks", ms=5, label=f"Ghia et al. (1982), Re = {exp.ghia_re}")
    for m, row in zip(exp.methods, rows):
        p = np.load(S.profiles_path(results, m.name, dx))
        c = COLORS.get(m.name)
        ax_u.plot(p["u"], p["y"], color=c, lw=1.6,
                  label=f"{LABELS.get(m.name, m.name)} (RMS dev. {row['u_rms']:.3f})")
        ax_v.plot(p["x"], p["v"], color=c, lw=1.6,
                  label=f"{LABELS.get(m.name, m.name)} (RMS dev. {row['v_rms']:.3f})")
    t_from, t_to = rows[0]["avg_t_from"], rows[0]["avg_t_to"]
    ax_u.set(xlabel="u", ylabel="y", title=f"u(y) at x = 0.5 (mean over t = {t_from:.3g}-{t_to:.3g})")
    ax_v.set(xlabel="x", ylabel="v", title=f"v(x) at y = 0.5 (mean over t = {t_from:.3g}-{t_to:.3g})")
    for ax in (ax_u, ax_v):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.canvas.draw()  # settle the layout, then size each marker to one particle spacing
    for ax, spacing, span, artists in scatters:
        width_pt = ax.get_window_extent().width * 72.0 / fig.dpi
        for a in artists:
            a.set_sizes([(1.05 * width_pt * spacing / span) ** 2])
    n_fluid = rows[0]["n_fluid"]
    fig.suptitle(f"2D lid-driven cavity, Re = {exp.re:g}, dx = {dx:g} ({n_fluid} fluid particles)")
    for ext in ("png", "pdf"):
        fig.savefig(out / f"{fig_name}.{ext}", dpi=150)
    plt.close(fig)
    pd.DataFrame(rows).to_csv(out / "metrics.csv", index=False)  # exactly this figure's runs, as evaluated
    print(f"{fig_name} -> {out / (fig_name + '.png')}, {out / 'metrics.csv'}")
    for row in rows:
        print(f"  {row['method']:8s} dx {dx:g}: RMS dev. u {row['u_rms']:.4f} v {row['v_rms']:.4f}, "
              f"max dev. u {row['u_maxdev']:.4f} v {row['v_maxdev']:.4f}")
    return out / f"{fig_name}.png"


def options(ap):
    ap.add_argument("--fig", choices=S.FIGURES, required=True)
    ap.add_argument("--gif", default=None, help="write only an animation of one run of the figure to this file")
    ap.add_argument("--method", default="tvf", help="the method animated with --gif (default tvf)")


def main(args):
    exp, results = S.load(args.profile), args.results
    if args.gif:
        names = [m.name for m in exp.methods]
        if args.method not in names:
            raise SystemExit(f"--method {args.method}: not a method of this profile ({names})")
        animate.render(S.run_dir(results, args.method, float(exp.figures[args.fig])) / "traj.h5", args.gif)
    else:
        plot(exp, results, args.fig)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
