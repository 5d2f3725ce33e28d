"""Fig. 8: dam break, non-dimensional pressure p/(rho g H) of the particles of the 2:1 column at the
paper's time stamps (one panel each, fixed colour range), and a validation figure with the
downstream-wall pressure history against Buchner (2002) and the square column's surge front and
back-wall height against Martin & Moyce (1952).

Reads the current runs and metrics.csv (lab.experiment: refused, naming them, when a run is missing or
stale; the per-frame series are analysis.py's); writes <out>/fig8.{png,pdf}, validation.{png,pdf}
and metrics.csv (a copy; make: results/<profile>/fig8/); with --gif PATH only an animation of the
Fig. 8 column's pressure in the figure's colour range (lab.animate).

    python experiments/dambreak2d/plot_fig8.py --profile smoke [--results results/smoke] [--out DIR] [--gif fig8.gif]
"""
import shutil

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Rectangle  # noqa: E402
import numpy as np  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402
import sph  # noqa: E402


def column_run(exp, name: str):
    """The run of column `name`."""
    return next(r for r in exp.runs if r.column.name == name)


def column_series(exp, name: str):
    """The per-frame series of column `name` (analysis.py)."""
    run = column_run(exp, name)
    return exp.analysis.series(exp.settings, run.column, exp.trajectory(run))[0]


def _draw_tank(ax, s):
    """The wall layers as grey bands around the tank interior [0, L] x [0, H_tank]."""
    t, L, H = s.offset, s.tank.length, s.tank.height
    for xy, w, h in (((-t, -t), L + 2 * t, t), ((-t, H), L + 2 * t, t), ((-t, 0), t, H), ((L, 0), t, H)):
        ax.add_patch(Rectangle(xy, w, h, facecolor="0.75", edgecolor="none"))


def plot_fig8(experiment, out):
    exp = experiment.settings
    column = exp.column(exp.pressure_column)
    tr = experiment.trajectory(column_run(experiment, column.name))
    t, pos, p = tr["time"], tr["position"], tr["pressure"]
    fluid = tr["particle_type"] == sph.FLUID
    off, scale = exp.offset, exp.fluid.rho_ref * exp.g * column.height
    times = list(exp.snapshot_times)
    ncol = 3 if len(times) > 4 else len(times)
    nrow = -(-len(times) // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(4.6 * ncol, 2.1 * nrow + 0.6), constrained_layout=True,
                             squeeze=False)
    lo, hi = exp.pressure_range
    size = max(0.3, 1.6 * (exp.dx / 0.02) ** 2)
    sc = None
    for ax, ts in zip(axes.flat, times):
        k = int(np.argmin(np.abs(t - ts)))
        x, y = pos[k, :, 0] - off, pos[k, :, 1] - off
        _draw_tank(ax, exp)
        sc = ax.scatter(x[fluid], y[fluid], s=size, c=p[k, fluid] / scale, cmap="viridis", vmin=lo, vmax=hi,
                        linewidths=0)
        late = "" if abs(t[k] - ts) < 0.5 * exp.frame_dt + 1e-9 else f" (run ends at {t[-1]:.2f})"
        ax.set_title(rf"$t\sqrt{{g/H}}$ = {t[k]:.2f}{late}", fontsize=10)
        ax.set(xlim=(-exp.offset, exp.tank.length + exp.offset), ylim=(-exp.offset, exp.tank.height + exp.offset),
               aspect="equal", xticks=[0, 1, 2, 3, 4, 5], yticks=[0, 1, 2])
    for ax in axes[-1, :]:
        ax.set_xlabel("x / H")
    for ax in axes[:, 0]:
        ax.set_ylabel("y / H")
    for ax in list(axes.flat)[len(times):]:
        ax.axis("off")
    fig.colorbar(sc, ax=axes, shrink=0.8, label=r"$p/(\rho g H)$")
    fig.suptitle(f"Dam break, Riemann SPH, dx = {exp.dx:g} H, {column.width:g} x {column.height:g} column, "
                 f"{exp.effects.walls} walls")
    save_figure(fig, out, "fig8")
    return out / "fig8.png"


def plot_validation(experiment, out):
    exp, E = experiment.settings, experiment.analysis
    metrics = experiment.table().set_index("column")
    fig, (ax_p, ax_f, ax_h) = plt.subplots(1, 3, figsize=(15.0, 4.0), constrained_layout=True)

    col = exp.pressure_column
    s = column_series(experiment, col)
    t_ref, p_ref = E.load_ref(E.BUCHNER)
    ax_p.plot(t_ref, p_ref, "ko", ms=3, label="Buchner (2002), experiment")
    ax_p.plot(s["t"], s["p_sensor"], "-", color="tab:blue", lw=0.6, alpha=0.6,
              label=f"SPH, every frame (dx = {exp.dx:g})")
    ax_p.plot(s["t"], s["p_sensor_smooth"], "-", color="tab:red", lw=1.5,
              label=f"SPH, running mean over {exp.smooth_window:g}")
    m = metrics.loc[col]
    ax_p.plot([m["ref_p_peak_t"]], [m["ref_p_peak"]], "s", mfc="none", mec="k", ms=9, label="first peak, exp.")
    ax_p.plot([m["p_peak_t"]], [m["p_peak"]], "s", mfc="none", mec="tab:blue", ms=9, label="first peak, SPH")
    ax_p.plot([m["p_peak_t_smooth"]], [m["p_peak_smooth"]], "s", mfc="none", mec="tab:red", ms=9,
              label="first peak, SPH smoothed")
    lo, hi = min(-0.5, s["p_sensor"].min()), max(2.0, s["p_sensor"].max())
    clipped = lo < -1.0 or hi > 3.0
    ax_p.set(xlabel=r"$t\sqrt{g/H}$", ylabel=r"$p/(\rho g H)$",
             title=f"downstream wall, y = {exp.sensor_height:g} H ({exp.column(col).width:g}:1 column)"
                   + (f"\n(raw SPH spans [{s['p_sensor'].min():.2g}, {s['p_sensor'].max():.2g}], clipped)"
                      if clipped else ""),
             xlim=(0, max(s["t"].iloc[-1], t_ref[-1])), ylim=(max(lo, -1.0), min(hi, 3.0)))
    ax_p.legend(fontsize=8)

    col = exp.front_column
    s = column_series(experiment, col)
    tf, xf = E.load_ref(E.MM_FRONT)
    th, yh = E.load_ref(E.MM_HEIGHT)
    ax_f.plot(tf, xf, "ko", ms=4, label="Martin & Moyce (1952)")
    ax_f.plot(s["t"], s["x_front"], color="tab:red", label=f"SPH (dx = {exp.dx:g})")
    ax_f.axvline(exp.front_t_max, color="0.5", ls=":", lw=1)
    ax_f.axhline(exp.tank.length / exp.column(col).height, color="0.5", ls="--", lw=1, label="right wall")
    m = metrics.loc[col]
    ax_f.set(xlabel=r"$t\sqrt{g/H}$", ylabel=r"$x_{front}/H$", xlim=(0, 3.5),
             title=f"square column: surge front (max. rel. err. {m['front_relerr_max']:.1%} "
                   rf"for $t\sqrt{{g/H}} \leq$ {exp.front_t_max:g})")
    ax_f.legend(fontsize=8)
    ax_h.plot(th, yh, "ko", ms=4, label="Martin & Moyce (1952)")
    ax_h.plot(s["t"], s["h_back"], color="tab:red", label=f"SPH (dx = {exp.dx:g})")
    ax_h.set(xlabel=r"$t\sqrt{g/H}$", ylabel=r"$h(x=0)/H$", xlim=(0, max(s["t"].iloc[-1], 0.5)),
             title="square column: height at the back wall")
    ax_h.legend(fontsize=8)
    for ax in (ax_p, ax_f, ax_h):
        ax.grid(True, alpha=0.3)
    save_figure(fig, out, "validation")
    return out / "validation.png"


def fig8_gif(experiment):
    """The Fig. 8 column's run and its animation's colour range of p / (rho g H) (plot_main's --gif)."""
    exp = experiment.settings
    column = exp.column(exp.pressure_column)
    scale = exp.fluid.rho_ref * exp.g * column.height
    lo, hi = exp.pressure_range
    return column_run(experiment, column.name), {"field": "pressure", "vmin": lo * scale, "vmax": hi * scale}


def plot(experiment, out):
    f8 = plot_fig8(experiment, out)
    plot_validation(experiment, out)
    shutil.copyfile(experiment.metrics_path, out / "metrics.csv")
    return f8


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__, gif=fig8_gif)
