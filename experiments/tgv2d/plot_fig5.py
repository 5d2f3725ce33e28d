"""Fig. 5: maximum velocity u_max(t) and kinetic energy E_kin(t) of the 2D Taylor-Green vortex for
every method and dx of the profile, against the analytical decay (log scale).

Reads the current runs and metrics.csv (lab.experiment: refused, naming them, when a run of the
profile is missing or stale); writes <out>/fig5.{png,pdf} and <out>/metrics.csv, a copy of the table
(make: results/<profile>/fig5/).

    python experiments/tgv2d/plot_fig5.py --profile smoke [--results results/smoke] [--out DIR]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import method_lines, save_figure  # noqa: E402
from sph.cases import tgv  # noqa: E402


def plot(exp, out):
    s = exp.settings
    table = exp.table()
    fig, (ax_u, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.0), constrained_layout=True)
    t = np.linspace(0.0, s.t_end, 200)
    ax_u.plot(t, tgv.u_max_exact(t, s.re), "k", lw=3, alpha=0.25, label="analytical")
    ax_e.plot(t, tgv.e_kin_exact(t, s.re), "k", lw=3, alpha=0.25, label="analytical")
    for m, dx, label, style in method_lines(s.methods, sorted(s.dx)):  # finest first: solid lines
        tr = exp.trajectory(exp.run(exp.study.run_name(m.name, dx)))
        ax_u.plot(tr["time"], tr["u_max"], label=f"{label}, dx = {dx:g}", lw=1.4, **style)
        ax_e.plot(tr["time"], tr["e_kin"], label=f"{label}, dx = {dx:g}", lw=1.4, **style)
    ax_u.set(yscale="log", xlabel="t", ylabel=r"$u_{max}$", xlim=(0, s.t_end),
             title=r"max. velocity, exact $e^{-8\pi^2 t/Re}$")
    ax_e.set(yscale="log", xlabel="t", ylabel=r"$E_{kin}$", xlim=(0, s.t_end),
             title=r"kinetic energy, exact $0.25\,e^{-16\pi^2 t/Re}$")
    ax_e.legend(fontsize=8, ncol=1)
    for ax in (ax_u, ax_e):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(f"2D Taylor-Green vortex, Re = {s.re:g}")
    png = save_figure(fig, out, "fig5")
    table.to_csv(Path(out) / "metrics.csv", index=False)
    return png


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
