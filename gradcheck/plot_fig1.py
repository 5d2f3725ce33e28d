"""Fig. 1 (gradient check): one row per case; the particles at the start of the checked window coloured by
the magnitude of their gradient |dE_kin/dr_i| from automatic differentiation (float64) and from central
finite differences (one column per entry of `fig1_dtypes`), walls in grey; on the right the eps sweep:
relative L2 error of the central difference against grad . d over random unit directions d, for
every case and precision, with the eps^2 (truncation) and 1/eps (round-off) slopes.

Reads the check runs of study.py (<results>/gradcheck/<case>_<dtype>/check.npz, metrics.csv); writes
<out>/{fig1.png, fig1.pdf, metrics.csv (a copy), sweep.csv (the eps sweep, study.sweep_rows)}
(`make fig1`: <out> = <results>/fig1).

    python gradcheck/plot_fig1.py --profile smoke [--results results/smoke] [--out results/smoke/fig1]
"""
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402
from sph.state import FLUID  # noqa: E402

TITLES = {"tgv": "Taylor-Green vortex", "ldc": "lid-driven cavity"}
DTYPE_STYLE = {"float64": "-", "float32": "--"}


def _magnitude(g):
    return np.linalg.norm(g, axis=1)


def plot(experiment, out: Path) -> Path:
    exp, study = experiment.settings, experiment.study
    checks = study.check_runs(exp)
    folder = {(r.case.name, r.dtype): experiment.out_dir / r.name for r in checks}
    metrics = experiment.table(checks)
    sweep = pd.DataFrame([row for r in checks for row in study.sweep_rows(r, folder[r.case.name, r.dtype])],
                         columns=study.SWEEP_COLUMNS)
    cols = 1 + len(exp.fig1_dtypes)
    rows = len(exp.cases)
    fig = plt.figure(figsize=(3.3 * cols + 4.6, 3.1 * rows + 0.4), constrained_layout=True)
    grid = fig.add_gridspec(rows, cols + 1, width_ratios=[1.0] * cols + [1.35])
    for i, case in enumerate(exp.cases):
        z = study.check_arrays(folder[case.name, "float64"])
        r, tag, mag_ad = z["r"], z["tag"], _magnitude(z["g_ad"])
        fluid = tag == FLUID
        panels = [("AD, float64", r, tag, mag_ad)]
        for dtype in exp.fig1_dtypes:
            z = study.check_arrays(folder[case.name, dtype])
            row = metrics[(metrics["case"] == case.name) & (metrics["dtype"] == dtype)].iloc[0]
            label = f"FD, {dtype}\nrel. L2 err. {row['rel_l2']:.1e}, MSE {row['mse']:.1e}"
            panels.append((label, z["r"], z["tag"], _magnitude(z["g_fd"])))
        vmax = float(np.nanmax(mag_ad))
        for j, (label, rr, tt, mag) in enumerate(panels):
            ax = fig.add_subplot(grid[i, j])
            wall = tt != FLUID
            if wall.any():
                ax.scatter(rr[wall, 0], rr[wall, 1], s=4, c="0.8", lw=0)
            fl = tt == FLUID
            sc = ax.scatter(rr[fl, 0], rr[fl, 1], s=max(4.0, 3200.0 / fl.sum()), c=mag, cmap="viridis",
                            vmin=0.0, vmax=vmax, lw=0)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(label, fontsize=8.5)
            if j == 0:
                ax.set_ylabel(TITLES.get(case.kind, case.name) + f" ({fluid.sum()} fluid)", fontsize=9)
        fig.colorbar(sc, ax=ax, shrink=0.85, label=r"$|\partial E_{kin} / \partial \mathbf{r}_i|$")
    ax = fig.add_subplot(grid[:, cols])
    for i, case in enumerate(exp.cases):
        for dtype in exp.dtypes:
            sel = sweep[(sweep["case"] == case.name) & (sweep["dtype"] == dtype)].sort_values("eps_factor")
            ax.loglog(sel["eps_factor"], sel["rel_l2"], DTYPE_STYLE.get(dtype, ":"), marker="o", ms=4,
                      color=f"C{i}", label=f"{TITLES.get(case.kind, case.name)}, {dtype}")
    ref = sweep[(sweep["dtype"] == "float64")]
    if len(ref):  # guide slopes anchored at the float64 errors of the first case
        sel = ref[ref["case"] == exp.cases[0].name].sort_values("eps_factor")
        e_hi, err_hi = sel["eps_factor"].iloc[-1], sel["rel_l2"].iloc[-1]
        e_lo, err_lo = sel["eps_factor"].iloc[0], sel["rel_l2"].iloc[0]
        x = np.geomspace(e_hi * 1e-2, e_hi, 10)
        ax.loglog(x, 0.2 * err_hi * (x / e_hi) ** 2, color="0.4", ls=":", lw=1.2,
                  label=r"$\propto \epsilon^2$ (truncation)")
        x = np.geomspace(e_lo, e_lo * 1e2, 10)
        ax.loglog(x, 0.2 * err_lo * (e_lo / x), color="0.4", ls="-.", lw=1.2,
                  label=r"$\propto 1/\epsilon$ (round-off)")
    ax.axvline(exp.eps_factor, color="0.5", lw=0.8)
    ax.text(exp.eps_factor, 0.98, r" paper $\epsilon$", transform=ax.get_xaxis_transform(), va="top", fontsize=8)
    n_dir = int(sweep["n_directions"].iloc[0]) if len(sweep) else 0
    ax.set(xlabel=r"$\epsilon / \Delta x$", ylabel="relative L2 error, FD vs AD",
           title=f"step-size sweep ({n_dir} random directions)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7.5)
    fig.suptitle(rf"Gradient check: $\partial E_{{kin}}(t_{{{exp.warmup_steps}+{exp.loss_steps}}})"
                 rf" / \partial \mathbf{{r}}(t_{{{exp.warmup_steps}}})$, AD vs central FD, "
                 rf"$\epsilon$ = {exp.eps:g}, $\Delta x$ = {exp.dx:g}", fontsize=10)
    save_figure(fig, out, "fig1")
    shutil.copyfile(experiment.metrics_path, out / "metrics.csv")
    sweep.to_csv(out / "sweep.csv", index=False)
    print(f"fig1 -> {out / 'fig1.png'}, {out / 'metrics.csv'}")
    return out / "fig1.png"


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
