"""Fig. 6: 2D lid-driven cavity at Re = 100 at figures.fig6's dx (paper: 0.02). Top: velocity magnitude of
the particles at t_end, one panel per method. Bottom: centreline profiles u(y) at x = 0.5 and v(x) at
y = 0.5 of each method (SPH interpolation averaged over the last frames, analysis.py) against Ghia et
al. (1982). plot_fig7.py draws Fig. 7 (figures.fig7's dx, paper 0.01) with this script's `figure`.

Reads the current runs of the figure (lab.experiment: refused, naming them, when one is missing or
stale), evaluated by analysis.py; writes <out>/fig6.{png,pdf} and <out>/metrics.csv (the metrics rows
of that dx; make: results/<profile>/fig6/); with --gif PATH only an animation of the TVF run of the
figure (else its first method's; lab.animate).

    python experiments/ldc2d/plot_fig6.py --profile smoke [--results results/smoke] [--out DIR] [--gif fig6.gif]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from sph.cases import ldc_reference  # noqa: E402
from sph.state import FLUID, MOVING_WALL  # noqa: E402
from lab.experiment import plot_main  # noqa: E402
from lab.io import read_metadata, read_trajectory  # noqa: E402

COLORS = {"sph": "tab:blue", "tvf": "tab:orange", "riemann": "tab:green"}
LABELS = {"sph": "SPH", "tvf": "SPH + TVF", "riemann": "Riemann SPH"}


def figure_runs(experiment, fig_name: str) -> list:
    """The runs `fig_name` shows (its dx), one per method, refused when the profile has no such figure."""
    exp = experiment.settings
    if fig_name not in exp.figures:
        raise SystemExit(f"profile has no {fig_name} (figures: {list(exp.figures)})")
    return [r for r in experiment.runs if fig_name in r.groups]


def figure(experiment, out, fig_name: str) -> Path:
    """Fig. 6 or 7 (`fig_name`) of the current runs at its dx into `out`, with its metrics.csv (the rows of
    exactly its runs, as evaluated)."""
    exp = experiment.settings
    dx = float(exp.figures[fig_name])
    runs = figure_runs(experiment, fig_name)
    evaluated = [experiment.analysis.evaluate(exp, r.method, r.dx, experiment.current(r).folder) for r in runs]
    rows, lines = [e[0] for e in evaluated], [e[1] for e in evaluated]

    n = len(exp.methods)
    fig = plt.figure(figsize=(4.0 * n, 8.2), constrained_layout=True)
    gs = fig.add_gridspec(2, 2 * n)
    field_axes = [fig.add_subplot(gs[0, 2 * i:2 * i + 2]) for i in range(n)]
    ax_u = fig.add_subplot(gs[1, :n])
    ax_v = fig.add_subplot(gs[1, n:])
    vmax = exp.lid_velocity
    scatters = []
    for ax, m, run in zip(field_axes, exp.methods, runs):
        spec = experiment.current(run)
        tr = read_trajectory(spec.traj)
        meta_off = float(read_metadata(spec.meta_path)["cavity_offset"])
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
    for m, row, p in zip(exp.methods, rows, lines):
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
    for row in rows:
        print(f"  {row['method']:8s} dx {dx:g}: RMS dev. u {row['u_rms']:.4f} v {row['v_rms']:.4f}, "
              f"max dev. u {row['u_maxdev']:.4f} v {row['v_maxdev']:.4f}")
    return out / f"{fig_name}.png"


def plot(experiment, out):
    return figure(experiment, out, "fig6")


def gif_run(experiment, fig_name: str = "fig6"):
    """The run the figure's animation shows: its TVF run, else its first method's."""
    runs = figure_runs(experiment, fig_name)
    return next((r for r in runs if r.method == "tvf"), runs[0])


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__, gif=gif_run)
