"""Fig. 9: kinetic-energy dissipation rate -dE/dt(t) (left) and kinetic energy E_kin(t) (right) of the
3D Taylor-Green vortex at Re = 100, every method and resolution of the profile, against the
JAX-Fluids reference (open circles), log scale as in the paper.

Reads the current runs (the per-frame series only, analysis.read_trajectory) and metrics.csv
(lab.experiment: refused, naming them, when a run is missing or stale); writes <out>/fig9.{png,pdf}
and <out>/metrics.csv (a copy of the run metrics; make: results/<profile>/fig9/).

    python experiments/tgv3d/plot_fig9.py --profile smoke [--results results/smoke] [--out DIR]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import method_lines, save_figure  # noqa: E402


def plot(experiment, out):
    exp, analysis = experiment.settings, experiment.analysis
    table = experiment.table()
    ref = analysis.load_reference(exp)
    fig, (ax_d, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.2), constrained_layout=True)
    shown = ref["t"] <= exp.t_end * (1 + 1e-9)
    every = max(1, int(shown.sum()) // 50)
    dots = dict(s=18, facecolors="none", edgecolors="k", lw=0.8, zorder=3, label="JAX-Fluids (reference)")
    ax_d.scatter(ref["t"][shown][::every], ref["dissipation"][shown][::every], **dots)
    ax_e.scatter(ref["t"][shown][::every], ref["e_kin"][shown][::every], **dots)
    for m, n, label, style in method_lines(exp.methods, sorted(exp.n_side, reverse=True)):  # finest first: solid
        s = analysis.energy_series(exp, experiment.trajectory(experiment.run(experiment.study.run_name(m.name, n))))
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
    table.to_csv(Path(out) / "metrics.csv", index=False)
    return png


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
