"""Fig. 4: velocity magnitude per particle of the 2D Taylor-Green vortex at t = 0 and t = t_end
(method `fig4_method`, default TVF, at the finest dx of the profile).

Reads results/<profile>/tgv2d/<method>_dx<dx>/traj.h5; writes results/<profile>/fig4/fig4.{png,pdf}, or
with --gif PATH only an animation of the same run (lab.animate).

    python experiments/tgv2d/plot_fig4.py --profile smoke [--results results/smoke] [--gif fig4.gif]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab.figures import figure_dir, save_figure  # noqa: E402
from lab import animate, io  # noqa: E402
try:  # noqa: E402
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S


def fig4_traj(exp: "S.Experiment", results) -> Path:
    """The trajectory Fig. 4 shows: `fig4_method` at the finest dx."""
    return S.run_dir(results, exp.fig4_method, min(exp.dx)) / "traj.h5"


def plot(exp: "S.Experiment", results, out=None) -> Path:
    dx = min(exp.dx)
    traj = io.read_trajectory(fig4_traj(exp, results))
    if "velocity" not in traj:
        raise SystemExit("fig4 needs the velocity field: add 'velocity' to `keep` in config.yaml")
    out = figure_dir(results, "fig4", out)
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
    fig.suptitle(f"2D Taylor-Green vortex, Re = {exp.re:g}, {exp.fig4_method.upper()}, dx = {dx:g} "
                 f"({traj['particle_type'].shape[0]} particles)")
    save_figure(fig, out, "fig4")
    print(f"fig4 -> {out / 'fig4.png'}")
    return out / "fig4.png"


def options(ap):
    ap.add_argument("--out", default=None, help="figure folder (default <results>/fig4)")
    ap.add_argument("--gif", default=None, help="write only an animation of the Fig. 4 run to this file")


def main(args):
    exp, results = S.load(args.profile), args.results
    if args.gif:
        animate.render(fig4_traj(exp, results), args.gif)
    else:
        plot(exp, results, args.out)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
