"""Fig. 10: non-dimensional temperature theta = (T - T_ref) / (T_hot - T_ref) of every particle (fluid
and walls) of JAX-SPH's hot channel at the profile's `snapshot_times` (nearest written frame), on a
fixed colour range [0, 1]; plus fig10_series: heated-wall Nusselt number, outlet and maximum fluid
temperature and the bulk velocity against start-up Poiseuille flow over time.

Reads the current channel run and channel_metrics.csv (lab.experiment: refused, naming them, when
the run is missing or stale); writes <out>/fig10.{png,pdf}, fig10_series.png, metrics.csv (the
channel metrics row of this dx) and series.csv (the per-frame diagnostics, study.channel_series;
make: results/<profile>/fig10/).

    python experiments/thermal/plot_fig10.py --profile smoke [--results results/smoke] [--out DIR]
"""

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402
from sph.state import FLUID  # noqa: E402

CMAP = "inferno"


def snapshot_indices(times, wanted) -> list:
    """Index of the frame nearest to each wanted time."""
    times = np.asarray(times)
    return [int(np.argmin(np.abs(times - t))) for t in wanted]


def periodic_copies(r, values, length: float, margin: float):
    """Append copies of the particles within `margin` of x = 0 or x = length shifted by -+length, so
    that the markers of a periodic channel cover both ends of the plot."""
    left, right = r[:, 0] < margin, r[:, 0] > length - margin
    shift = np.array([length, 0.0])
    return (np.concatenate([r, r[left] + shift, r[right] - shift]),
            np.concatenate([values, values[left], values[right]]))


def plot(exp, out):
    c = exp.settings.channel
    run = next(r for r in exp.runs if r.kind == "channel")
    table = exp.table([run])
    data = exp.trajectory(run)
    series = exp.study.channel_series(run, data)
    box = np.array([hi for _, hi in data["metadata"]["bounds"]])
    dT = c.T_hot - c.T_ref
    idx = snapshot_indices(data["time"], c.snapshot_times)
    width = 8.0
    panel_h = width * 0.82 * box[1] / box[0]
    fig, axes = plt.subplots(len(idx), 1, figsize=(width, 0.9 + len(idx) * (panel_h + 0.25)),
                             constrained_layout=True, squeeze=False, sharex=True)
    size = (1.2 * 0.82 * width * 72 * c.dx / box[0]) ** 2  # squares slightly over one spacing (points^2)
    fluid = data["particle_type"] == FLUID
    for ax, k in zip(axes[:, 0], idx):
        r, theta = periodic_copies(data["position"][k], (data["temperature"][k] - c.T_ref) / dT, box[0], 2 * c.dx)
        sc = ax.scatter(r[:, 0], r[:, 1], c=theta, s=size, marker="s", linewidths=0, cmap=CMAP, vmin=0.0, vmax=1.0)
        rw = data["position"][k][~fluid]
        ax.scatter(rw[:, 0], rw[:, 1], s=size * 0.08, c="w", marker=".", linewidths=0, alpha=0.5)
        ax.set(xlim=(0, box[0]), ylim=(0, box[1]), aspect="equal", yticks=[0, box[1]], ylabel="y")
        ax.set_title(f"t = {data['time'][k]:.3g}", fontsize=9, loc="left", pad=2)
    axes[-1, 0].set_xlabel("x")
    fig.colorbar(sc, ax=axes[:, 0].tolist(), label=r"$\theta = (T - T_{ref})/(T_{hot} - T_{ref})$",
                 shrink=0.8, aspect=30)
    fig.suptitle(f"Hot channel (JAX-SPH Fig. 10): standard SPH + heat, dx = {c.dx:g}, {int(fluid.sum())} fluid "
                 f"particles\nwalls dotted; heated bottom segment |x - {box[0] / 2:g}| < {c.hot_half_width:g} "
                 f"at T_hot = {c.T_hot:g}, other walls at T_ref = {c.T_ref:g}", fontsize=9)
    save_figure(fig, out, "fig10")

    t = series["time"]
    fig, ax = plt.subplots(1, 3, figsize=(12.0, 3.4), constrained_layout=True)
    ax[0].plot(t, series["Nu_hot"], "C3")
    ax[0].set(xlabel="t", ylabel=r"$Nu_{hot} = \bar q_{hot} H / (\kappa \Delta T)$", title="heated-wall heat flux",
              ylim=(0, None))
    ax[1].plot(t, (series["T_fluid_max"] - c.T_ref) / dT, "C1", label=r"max $\theta$ (fluid)")
    ax[1].plot(t, (series["T_fluid_mean"] - c.T_ref) / dT, "C2", label=r"mean $\theta$ (fluid)")
    ax[1].plot(t, (series["T_outlet_bulk"] - c.T_ref) / dT, "C0", label=r"outlet $\theta$ (mixing cup)")
    ax[1].set(xlabel="t", ylabel=r"$\theta$", ylim=(0, 1), title="temperatures")
    ax[1].legend(fontsize=8)
    ax[2].plot(t, series["u_bulk"], "C0", label="SPH, mean $u_x$")
    ax[2].plot(t, series["u_bulk_exact"], "k--", label="start-up Poiseuille")
    ax[2].set(xlabel="t", ylabel=r"$u_{bulk}$", title="bulk velocity")
    ax[2].legend(fontsize=8)
    for a in ax:
        a.grid(alpha=0.3)
    fig.savefig(out / "fig10_series.png", dpi=150)
    plt.close(fig)
    table[np.isclose(table["dx"], c.dx)].to_csv(out / "metrics.csv", index=False)
    series.to_csv(out / "series.csv", index=False)
    return out / "fig10.png"


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
