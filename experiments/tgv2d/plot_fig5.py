"""Fig. 5: maximum velocity u_max(t) and kinetic energy E_kin(t) of the 2D Taylor-Green vortex for
every method and dx of the profile, against the analytical decay (log scale).

Reads results/<profile>/tgv2d/*/traj.h5 and metrics.csv; writes results/<profile>/fig5/fig5.{png,pdf}
and results/<profile>/fig5/metrics.csv (a copy of the run metrics).

    python experiments/tgv2d/plot_fig5.py --profile smoke [--results results/smoke]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab import io  # noqa: E402
from lab.figures import copy_metrics, figure_dir, method_lines, save_figure  # noqa: E402
from sph.cases import tgv  # noqa: E402
try:  # noqa: E402
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S


def plot(exp: "S.Experiment", results, out=None) -> Path:
    out = figure_dir(results, "fig5", out)
    fig, (ax_u, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.0), constrained_layout=True)
    t = np.linspace(0.0, exp.t_end, 200)
    ax_u.plot(t, tgv.u_max_exact(t, exp.re), "k", lw=3, alpha=0.25, label="analytical")
    ax_e.plot(t, tgv.e_kin_exact(t, exp.re), "k", lw=3, alpha=0.25, label="analytical")
    for m, dx, label, style in method_lines(exp.methods, sorted(exp.dx)):  # finest first: solid lines
        tr = io.read_trajectory(S.run_dir(results, m.name, dx) / "traj.h5")
        ax_u.plot(tr["time"], tr["u_max"], label=f"{label}, dx = {dx:g}", lw=1.4, **style)
        ax_e.plot(tr["time"], tr["e_kin"], label=f"{label}, dx = {dx:g}", lw=1.4, **style)
    ax_u.set(yscale="log", xlabel="t", ylabel=r"$u_{max}$", xlim=(0, exp.t_end),
             title=r"max. velocity, exact $e^{-8\pi^2 t/Re}$")
    ax_e.set(yscale="log", xlabel="t", ylabel=r"$E_{kin}$", xlim=(0, exp.t_end),
             title=r"kinetic energy, exact $0.25\,e^{-16\pi^2 t/Re}$")
    ax_e.legend(fontsize=8, ncol=1)
    for ax in (ax_u, ax_e):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"2D Taylor-Green vortex, Re = {exp.re:g}")
    png = save_figure(fig, out, "fig5")
    copy_metrics(S.metrics_path(results), out, len(exp.methods) * len(exp.dx), "experiments/tgv2d/run.py")
    print(f"fig5 -> {png}, {out / 'metrics.csv'}")
    return png


if __name__ == "__main__":
    from lab.cli import figure_main

    figure_main(plot, S.load, __doc__, "fig5")
