"""Fig. 4: velocity magnitude per particle of the 2D Taylor-Green vortex at t = 0 and t = t_end
(method `fig4_method`, default TVF, at the finest dx of the profile).

Reads the current run (lab.experiment: refused, naming it, when it is missing or stale); writes
<out>/fig4.{png,pdf} (make: results/<profile>/fig4/), or with --gif PATH only an animation of the
same run (lab.animate).

    python experiments/tgv2d/plot_fig4.py --profile smoke [--results results/smoke] [--out DIR] [--gif fig4.gif]
"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402


def fig4_run(exp):
    """The run Fig. 4 shows: `fig4_method` at the finest dx."""
    s = exp.settings
    return exp.run(exp.study.run_name(s.fig4_method, min(s.dx)))


def plot(exp, out):
    s, dx = exp.settings, min(exp.settings.dx)
    traj = exp.trajectory(fig4_run(exp))
    if "velocity" not in traj:
        raise SystemExit("fig4 needs the velocity field: add 'velocity' to `keep` in config.yaml")
    fig, axes = plt.subplots(1, 2, figsize=(9.0, 4.0), constrained_layout=True)
    # marker area in points^2: a square of about one spacing on the ~3.2 in wide unit-square axes
    size = (1.15 * 3.2 * 72 * dx) ** 2
    for ax, k in zip(axes, (0, -1)):
        r, u = traj["position"][k], traj["velocity"][k]
        speed = np.linalg.norm(u, axis=1)
        sc = ax.scatter(r[:, 0], r[:, 1], c=speed, s=size, marker="s", linewidths=0, cmap="viridis",
                        vmin=0.0, vmax=speed.max())
        ax.set(xlim=(0, 1), ylim=(0, 1), aspect="equal", xlabel="x", ylabel="y",
               title=f"t = {traj['time'][k]:.3g}")
        fig.colorbar(sc, ax=ax, label="|u|", shrink=0.9)
    fig.suptitle(f"2D Taylor-Green vortex, Re = {s.re:g}, {s.fig4_method.upper()}, dx = {dx:g} "
                 f"({traj['particle_type'].shape[0]} particles)")
    return save_figure(fig, out, "fig4")


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__, gif=fig4_run)
