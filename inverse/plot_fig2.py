"""Fig. 2: the inverse problem. Per case (rows): the target's initial and final states, the optimization
path of `path_optimizer` (its initial-state iterates, coloured by iteration) from the displaced and
from the random start, and the loss curves of every optimizer (log scale).

Reads the runs of study.py (<results>/inverse/<run>/{result.json, paths.npz}, summary.csv); writes
<out>/fig2.{png,pdf}, metrics.csv (every run's iteration rows: case, start, optimizer, iteration, loss,
rmse_final, rmse_initial, wall_s, ...) and summary.csv (a copy of the runs' table) (`make fig2`:
<out> = <results>/fig2).

    python inverse/plot_fig2.py --profile smoke [--results results/smoke] [--out results/smoke/fig2]
"""
import shutil
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib import cm, colors  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from lab.experiment import plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402

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


def gather(experiment):
    """(the arrays of every run under the keys of Fig. 2's panels, every run's iteration rows): refused
    unless every run is current."""
    study, data, rows = experiment.study, {}, []
    experiment.table()  # every run current, its row in summary.csv
    for run in experiment.runs:
        traj = experiment.trajectory(run)
        z = study.paths(traj["folder"])
        key = f"{run.case.name}__{run.start.name}__{run.optimizer.name}"
        data.update({"walls": z["walls"], f"target_initial__{run.case.name}": z["target_initial"],
                     f"target_final__{run.case.name}": z["target_final"], f"path__{key}": z["path"],
                     f"finals__{key}": z["finals"]})
        rows.append(study.iteration_rows(traj))
    return data, pd.concat(rows, ignore_index=True)


def plot(experiment, out: Path) -> Path:
    exp, study = experiment.settings, experiment.study
    data, table = gather(experiment)
    off = study.offset(exp.dx, exp.layers)
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
    table.to_csv(out / "metrics.csv", index=False)
    shutil.copyfile(experiment.out_dir / "summary.csv", out / "summary.csv")
    print(f"fig2 -> {out / 'fig2.png'}, {out / 'metrics.csv'}")
    return out / "fig2.png"


if __name__ == "__main__":
    plot_main(plot, __file__, __doc__)
