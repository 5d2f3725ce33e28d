"""Fig. 2: the inverse problem. Per case (rows): the target's initial and final states, the optimization
path of `path_optimizer` (its initial-state iterates, coloured by iteration) from the displaced and
from the random start, and the loss curves of every optimizer (log scale).

Reads results/<profile>/inverse/{paths.npz, metrics.csv, summary.csv} (run.py); writes
results/<profile>/fig2/fig2.{png,pdf} and copies of metrics.csv and summary.csv there.

    python inverse/plot.py --profile smoke [--results results/smoke]
"""
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib import cm, colors  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from lab.figures import save_figure  # noqa: E402

try:  # noqa: E402
    from . import scene as cube
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import scene as cube
    import settings as S

STYLES = ["-", "--", ":", "-."]


def _state_panel(ax, data, exp, case, start, off, norm):
    key = f"{case}__{start}__{exp.path_optimizer}"
    walls = data["walls"] - off
    ax.scatter(walls[:, 0], walls[:, 1], s=4, marker="s", color="0.75", lw=0)
    path = data[f"path__{key}"] - off
    cmap = cm.viridis
    for k in range(path.shape[0]):
        ax.scatter(path[k, :, 0], path[k, :, 1], s=7, color=cmap(norm(k)), lw=0, zorder=2)
    ti, tf = data[f"target_initial__{case}"] - off, data[f"target_final__{case}"] - off
    ax.scatter(ti[:, 0], ti[:, 1], s=22, facecolor="none", edgecolor="k", lw=0.8, zorder=3, label="target initial")
    ax.scatter(tf[:, 0], tf[:, 1], s=14, color="tab:red", lw=0, zorder=3, label="target final")
    last = data[f"finals__{key}"][-1] - off
    ax.scatter(last[:, 0], last[:, 1], s=18, marker="x", color="tab:orange", lw=0.8, zorder=4,
               label="final of last iterate")
    pad = exp.layers * exp.dx
    ax.set(xlim=(-pad, exp.box_size + pad), ylim=(-pad, exp.box_size + pad), aspect="equal", xlabel="x", ylabel="y")
    ax.set_title(f"case {case}, {start} start ({exp.path_optimizer})", fontsize=10)
    ax.tick_params(labelsize=8)


def plot(exp: "S.Experiment", results) -> Path:
    results = Path(results)
    out = S.fig_dir(results)
    out.mkdir(parents=True, exist_ok=True)
    data = np.load(S.paths_path(results))
    table = pd.read_csv(S.metrics_path(results))
    off = cube.offset(exp.dx, exp.layers)
    norm = colors.Normalize(0, exp.iterations)
    n_cases, n_starts = len(exp.cases), len(exp.starts)
    # 9.6 in wide: at the README's ~800 px a 9-point label is ~10 px tall; every legend in one row
    # of its own below the panels, so that no legend hides a curve or a particle
    fig, axes = plt.subplots(n_cases, n_starts + 1, figsize=(9.6, 3.1 * n_cases + 1.1), layout="constrained",
                             squeeze=False)
    targets = dict(zip([c.name for c in exp.cases], exp.rmse_targets))
    for i, case in enumerate(exp.cases):
        for j, start in enumerate(exp.starts):
            _state_panel(axes[i, j], data, exp, case.name, start.name, off, norm)
        ax = axes[i, -1]
        for m, opt in enumerate(exp.optimizers):
            for j, start in enumerate(exp.starts):
                g = table[(table["case"] == case.name) & (table["optimizer"] == opt.name)
                          & (table["start"] == start.name)].sort_values("iteration")
                ax.plot(g["iteration"], g["loss"], color=f"C{m}", ls=STYLES[j % len(STYLES)], marker=".", ms=3,
                        lw=1.2)
        title = f"case {case.name}: loss"
        if case.name in targets:
            ax.axhline(targets[case.name] ** 2, color="k", lw=0.8, ls=":",
                       label=f"authors' notebook: RMSE after {exp.iterations} steps (squared)")
            title += f"\n(authors' notebook: RMSE {targets[case.name]:g})"
        ax.set(yscale="log", xlabel="optimizer iteration", ylabel="loss (MSE of final positions)")
        ax.set_title(title, fontsize=10)
        ax.tick_params(labelsize=8)
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.grid(True, which="both", alpha=0.3)
    # one legend for every panel, in columns: the states' markers; the optimizers (colour); the
    # starts (dash) and the notebook's value
    handles = axes[0, 0].get_legend_handles_labels()[0]
    handles += [Line2D([], [], color=f"C{m}", marker=".", ms=3, lw=1.2, label=f"{opt.name} (lr {opt.learning_rate:g})")
                for m, opt in enumerate(exp.optimizers)]
    handles += [Line2D([], [], color="0.4", ls=STYLES[j % len(STYLES)], lw=1.2, label=f"{start.name} start")
                for j, start in enumerate(exp.starts)]
    handles += [h for h, lab in zip(*axes[0, -1].get_legend_handles_labels()) if lab.startswith("authors'")]
    fig.legend(handles=handles, loc="outside lower center", ncols=3, fontsize=8, frameon=False,
               columnspacing=2.0, handlelength=2.5)
    fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cm.viridis), ax=axes[:, n_starts - 1], shrink=0.6,
                 label="iteration of the initial-state iterate")
    fig.suptitle(f"Inverse problem: recover the initial positions from the final ones "
                 f"(t = {exp.t_end:g}, {exp.n_fluid} particles)")
    save_figure(fig, out, "fig2")
    shutil.copyfile(S.metrics_path(results), out / "metrics.csv")
    shutil.copyfile(S.out_dir(results) / "summary.csv", out / "summary.csv")
    print(f"fig2 -> {out / 'fig2.png'}, {out / 'metrics.csv'}")
    return out / "fig2.png"


if __name__ == "__main__":
    from lab.cli import experiment_main

    experiment_main(plot, S.load, __doc__)
