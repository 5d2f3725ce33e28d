"""The gradient norm against rollout length (`make grad-growth`): |dE_kin(n)/dr0| and E_kin(n) against the
number of steps n, and the AD-vs-FD check along one direction.

Reads the growth runs' table (<results>/gradcheck/grad_growth.csv, study.py); writes
<out>/{grad_norm_vs_steps.png, grad_norm_vs_steps.pdf, grad_norm_vs_steps.csv} (`make grad-growth`:
<out> = <results>/fig1).

    python gradcheck/plot_grad_norm_vs_steps.py --profile smoke [--results results/smoke] [--out results/smoke/fig1]
"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402

TITLES = {"tgv": "Taylor-Green vortex", "ldc": "lid-driven cavity"}


def plot(experiment, out: Path) -> Path:
    exp = experiment.settings
    table = experiment.table(experiment.study.growth_runs(exp))
    fig, (ax_g, ax_e) = plt.subplots(1, 2, figsize=(10.0, 4.0), constrained_layout=True)
    for i, case in enumerate(exp.cases):
        sel = table[table["case"] == case.name].sort_values("n_steps")
        name = TITLES.get(case.kind, case.name)
        ax_g.loglog(sel["n_steps"], sel["grad_norm"], "o-", color=f"C{i}", label=rf"$|\nabla E_{{kin}}|$, {name}")
        ax_g.loglog(sel["n_steps"], sel["loss"], "s:", color=f"C{i}", ms=3, label=rf"$E_{{kin}}$, {name}")
        if np.isfinite(sel["fd_dir_relerr"]).any():
            ax_e.loglog(sel["n_steps"], sel["fd_dir_relerr"], "o-", color=f"C{i}", label=name)
    dt = float(table["t"].iloc[0] / table["n_steps"].iloc[0]) if len(table) else float("nan")
    ax_g.set(xlabel=f"rollout length n (steps of dt = {dt:.3g})", ylabel=r"$|\partial E_{kin}(n) / \partial \mathbf{r}_0|$ (L2), $E_{kin}(n)$",
             title=f"gradient w.r.t. the initial positions ({exp.growth.dtype})")
    ax_e.set(xlabel="rollout length n (steps)", ylabel=r"$|\nabla E \cdot d - \mathrm{FD}_d| / |\mathrm{FD}_d|$",
             title=rf"AD vs central FD along a random direction, $\epsilon$ = {exp.eps:.0e}")
    for ax in (ax_g, ax_e):
        ax.grid(True, which="both", alpha=0.3)
        if ax.has_data():
            ax.legend(fontsize=8)
    if not ax_e.has_data():
        ax_e.text(0.5, 0.5, "growth.fd_check is off", ha="center", transform=ax_e.transAxes)
    save_figure(fig, out, "grad_norm_vs_steps")
    table.drop(columns=["fingerprint"]).to_csv(out / "grad_norm_vs_steps.csv", index=False)
    print(f"growth -> {out / 'grad_norm_vs_steps.png'}, {out / 'grad_norm_vs_steps.csv'}")
    return out / "grad_norm_vs_steps.png"


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
