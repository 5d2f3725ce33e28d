"""The droplet's Laplace test: the pressure jump against time per resolution (its ratio to sigma / R),
the jump's error and the spurious currents against resolution, and the error against wall time.

Reads the current runs and metrics.csv (lab.experiment: refused, naming them, when a run of
the profile is missing or stale); writes <results>/droplet/laplace.{png,pdf}.

    python experiments/droplet/plot_laplace.py --profile smoke [--results results/smoke] [--out DIR]
"""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from sph.cases import droplet  # noqa: E402
from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402


def plot(exp, out):
    df = exp.table().sort_values("n_side")
    fig, (ax_t, ax_r, ax_c) = plt.subplots(1, 3, figsize=(13.0, 3.8), constrained_layout=True)
    for run in sorted(exp.runs, key=lambda r: r.n_side):
        tr = exp.trajectory(run)
        width = 3 * run.numerics.h_factor / run.n_side
        jump = [np.subtract(*droplet.laplace_jump(r, p, (0.5, 0.5), run.radius, width))
                for r, p in zip(tr["position"], tr["pressure"])]
        ax_t.plot(tr["time"], np.asarray(jump) / (run.sigma / run.radius), marker=".", label=f"R / dx = {run.radius * run.n_side:g}")
    s = exp.settings
    ax_t.axhline(1.0, color="k", lw=3, alpha=0.25, label=r"Laplace: $\sigma / R$")
    ax_t.axhspan(0.9, 1.1, color="k", alpha=0.06)
    ax_t.axvline(s.average_from, color="k", ls=":", lw=1)
    ax_t.set(xlabel="t", ylabel=r"$(p_{in} - p_{out}) \,/\, (\sigma / R)$", title="pressure jump (band: 10 %)")
    ax_t.legend(fontsize=8, loc="lower right")
    ax_r.loglog(df["radius_over_dx"], df["err_laplace"], "o-", label=r"$|\Delta p / (\sigma/R) - 1|$")
    ax_r.loglog(df["radius_over_dx"], df["err_u_spurious"], "s--", label=r"$\max|u| \,/\, \sqrt{\sigma/(\rho R)}$")
    ax_r.set(xlabel="R / dx", ylabel=f"error (mean over t >= {s.average_from:g})", title="against resolution")
    ax_r.legend(fontsize=8)
    ax_c.loglog(df["wall_s"], df["err_laplace"], "o-")
    for _, row in df.iterrows():
        ax_c.annotate(f"R/dx {row['radius_over_dx']:g}", (row["wall_s"], row["err_laplace"]), fontsize=7,
                      xytext=(4, 4), textcoords="offset points")
    ax_c.margins(0.2)
    ax_c.set(xlabel="wall time of the run [s]", ylabel=r"$|\Delta p / (\sigma/R) - 1|$", title="error against cost")
    for ax in (ax_t, ax_r, ax_c):
        ax.grid(True, which="both", alpha=0.3)
    fig.suptitle(rf"2D droplet at rest, $\sigma$ = {s.sigma:g}, R = {s.radius:g}: continuum surface force "
                 f"(Morris 2000), {exp.profile} profile")
    return save_figure(fig, out, "laplace")


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
