"""Fig. 9: kinetic-energy dissipation rate -dE/dt(t) (left) and kinetic energy E_kin(t) (right) of the
3D Taylor-Green vortex at Re = 100, every method and resolution of the profile, against the
JAX-Fluids reference (open circles), log scale as in the paper.

Reads results/<profile>/tgv3d/*/traj.h5 (the per-frame series only) and metrics.csv; writes
results/<profile>/fig9/fig9.{png,pdf} and results/<profile>/fig9/metrics.csv (a copy of the run metrics).

    python experiments/tgv3d/plot_fig9.py --profile smoke [--results results/smoke]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from lab.figures import copy_metrics, figure_dir, method_lines, save_figure  # noqa: E402
try:  # noqa: E402
    from . import analysis, settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import analysis
    import settings as S


def plot(exp: "S.Experiment", results, out=None) -> Path:
    out = figure_dir(results, "fig9", out)
    ref = analysis.load_reference(exp)
    fig, (ax_d, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.2), constrained_layout=True)
    shown = ref["t"] <= exp.t_end * (1 + 1e-9)
    every = max(1, int(shown.sum()) // 50)
    dots = dict(s=18, facecolors="none", edgecolors="k", lw=0.8, zorder=3, label="JAX-Fluids (reference)")
    ax_d.scatter(ref["t"][shown][::every], ref["dissipation"][shown][::every], **dots)
    ax_e.scatter(ref["t"][shown][::every], ref["e_kin"][shown][::every], **dots)
    for m, n, label, style in method_lines(exp.methods, sorted(exp.n_side, reverse=True)):  # finest first: solid
        s = analysis.energy_series(exp, analysis.read_series(S.run_dir(results, m.name, n) / "traj.h5"))
        ax_d.plot(s["t_mid"], s["dissipation"], label=f"{label}, ${n}^3$", lw=1.3, **style)
        ax_e.plot(s["t"], s["e_kin"], label=f"{label}, ${n}^3$", lw=1.3, **style)
    ax_d.set(yscale="log", xlabel="t", ylabel=r"$-dE_{kin}/dt$", xlim=(0, exp.t_end),
             title=f"dissipation rate (central differences over $\\Delta t$ = {exp.analysis.dissipation_span:g})")
    ax_e.set(yscale="log", xlabel="t", ylabel=r"$E_{kin}$", xlim=(0, exp.t_end),
             title=r"kinetic energy per volume, $\frac{1}{2}\sum m|v|^2 / (\rho (2\pi)^3)$")
    ax_e.legend(fontsize=7, ncol=1)
    for ax in (ax_d, ax_e):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"3D Taylor-Green vortex, Re = {exp.re:g} ({exp.start} start)")
    png = save_figure(fig, out, "fig9")
    copy_metrics(S.metrics_path(results), out, len(exp.methods) * len(exp.n_side), "experiments/tgv3d/run.py")
    print(f"fig9 -> {png}, {out / 'metrics.csv'}")
    return png


if __name__ == "__main__":
    from lab.cli import figure_main

    figure_main(plot, S.load, __doc__, "fig9")
