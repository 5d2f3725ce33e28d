"""The accuracy-cost atlas: every run record of a results folder side by side.

Reads (never re-runs) the run records (record.json, lab.record) of the TGV sweep (study.py: the
runs of its `parts`) and of the experiments in `gather` (cavity: Figs. 6-7, dam break: Fig. 8, heat-operator validation), plus the
gradient check's metrics (gradcheck/: AD vs FD error against AD time). Writes, into
results/<profile>/accuracy/:

  runs.csv          every run record found (one schema: lab.record.RECORD_COLUMNS + err_<name>)
  accuracy.png/pdf  one panel per problem in a grid of 3 columns: error against wall time
                    (log-log), colour per method, marker shape per kernel, fill per dtype, the Pareto
                    front (the runs no other run beats in both error and time) drawn; one shared
                    legend below the panels
  convergence.png   per problem: error against dx with the least-squares order per method, and wall
                    time against particle count with the fitted exponent
  accuracy.md       per problem and error level the cheapest run that reaches it, and the orders;
                    what gradient checkpointing costs (time and memory of the same gradient), read
                    from results/bench/grad_memory.csv when bench/bench_grad_memory.py has written it

    python experiments/accuracy/plot_accuracy.py --profile smoke [--results results/smoke] [--out DIR]
    python experiments/accuracy/plot_accuracy.py --from-runs docs/results/paper/accuracy/runs.csv [--out DIR]
        (re-draws accuracy.png alone from a runs.csv already written: `replot`)
"""
import json
import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from lab import stamp  # noqa: E402
from lab.deliver import note_input  # noqa: E402
from lab import other_load  # noqa: E402
from lab.experiment import load_settings, plot_main  # noqa: E402
from lab.figures import save_figure  # noqa: E402

HERE = Path(__file__).resolve().parent

PROBLEMS = {  # problem -> (experiment of its records, error column, what the error is)
    "Taylor-Green 2D": ("tgv2d", None, "time-averaged |u_max / exact - 1|"),
    "Taylor-Green 3D": ("tgv3d", "err_e_kin_rms_rel", "RMS of E_kin / E_kin(JAX-Fluids) - 1"),
    "lid-driven cavity": ("ldc2d", "err_ghia_rms", "RMS deviation from Ghia (u, v)"),
    "dam break": ("dambreak2d", "err_front_relerr_max", "max. surge-front error vs Martin & Moyce"),
    "heat operator": ("thermal", "err_decay_rate", "|decay rate / exact - 1|"),
    "gradients": ("gradcheck", "err_rel_l2", "||g_AD - g_FD|| / ||g_FD||"),
    # sitl/cost.py: a "run" is one 20-step test rollout (wall_s = 20 x inference time per coarse step)
    "Solver-in-the-Loop (RPF 2D)": ("sitl", "err_mse20", "MSE_20 of 20-step test rollouts"),
}


def current_records(root: Path) -> list:
    """The record.json files of exactly the current runs below `root`: those in a folder that a run
    stamp there lists (lab.stamp: a run of a method, dx, kernel or dtype removed from its
    profile is not), or every one when `root` has no stamp (an experiment run without make). The
    stamps and records read are the atlas's inputs (lab.deliver.note_input)."""
    if not root.exists():
        return []
    current = stamp.current_folders(root)
    note_input(*sorted(root.rglob("*.done")))
    found = []
    for p in sorted(root.rglob("record.json")):
        if current is None or any(q in current for q in (p.parent.resolve(), *p.parent.resolve().parents)):
            note_input(p)
            found.append(p)
    return found


def gather(atlas, results) -> pd.DataFrame:
    """The record.json of every current run below the sweep folder (<results>/accuracy) and the
    gathered experiments' folders (`current_records`), + gradcheck; `atlas`: the study's Settings."""
    results = Path(results)
    roots = [results / HERE.name] + [results / g for g in atlas.gather if g != "gradcheck"]
    rows = []
    for root in roots:
        for p in current_records(root):
            rec = json.loads(p.read_text())
            rec["folder"] = str(p.parent.relative_to(results))
            rows.append(rec)
    grad = results / "gradcheck" / "metrics.csv"
    note_input(grad)
    if grad.exists():
        for _, g in pd.read_csv(grad).iterrows():
            rows.append({"experiment": "gradcheck", "target": "fig1", "method": f"AD {g['case']}",
                         "effects": "", "kernel": "", "dx": g["dx"], "dim": 2, "dtype": g["dtype"],
                         "n_particles": g["n_particles"], "n_steps": g["loss_steps"], "dt": g["dt"],
                         "wall_s": g["ad_s"], "compile_s": g["ad_compile_s"], "err_rel_l2": g["rel_l2"],
                         "folder": "gradcheck"})
    return pd.DataFrame(rows)


def problem_table(runs: pd.DataFrame, atlas, name: str) -> pd.DataFrame:
    """The runs of one problem with columns label, error, wall_s, dx, n_particles."""
    exp, col, _ = PROBLEMS[name]
    col = col or f"err_{atlas.tgv.error}"
    if runs.empty or col not in runs:
        return pd.DataFrame(columns=["label", "error", "wall_s", "dx", "n_particles"])
    t = runs[(runs["experiment"] == exp) & runs[col].notna()].copy()
    t["error"] = t[col].abs()
    kern = t["kernel"].fillna("").astype(str)
    if "h_factor" in t:  # a smoothing length other than h = dx is part of the family's name
        h = pd.to_numeric(t["h_factor"], errors="coerce")
        kern = kern + np.where(h.notna() & (h != 1.0) & (kern != ""), " h=" + h.map("{:g}".format) + "dx", "")
    t["label"] = t["method"].astype(str) + np.where(kern != "", " " + kern, "") + " " + t["dtype"].astype(str)
    return t[t["error"] > 0].reset_index(drop=True)


def pareto(t: pd.DataFrame) -> pd.DataFrame:
    """Runs not beaten in both error and wall time by any other run, by increasing time."""
    t = t.sort_values(["wall_s", "error"])
    best, keep = np.inf, []
    for i, r in t.iterrows():
        if r["error"] < best:
            keep.append(i)
            best = r["error"]
    return t.loc[keep]


def fitted_order(x, y) -> float:
    """Least-squares slope of log y against log x (nan with fewer than two distinct x)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if len(np.unique(x[ok])) < 2:
        return float("nan")
    return float(np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)[0])


METHOD_COLORS = {"sph": "C0", "tvf": "C2", "riemann": "C3"}
KERNEL_MARKERS = {"quintic": "o", "wendland_c2": "s", "wendland_c4": "^"}
SPARE_COLORS, SPARE_MARKERS = ["C1", "C4", "C5", "C6", "C7", "C8", "C9"], "DvP*X<>ph"


def family_styles(t: pd.DataFrame) -> dict:
    """label -> matplotlib style of each run family of a problem table (or of every problem's tables
    concatenated, for one style across the atlas's panels): colour by method, marker by kernel (and
    smoothing length), filled for float64, open for float32."""
    styles, colors, markers = {}, dict(METHOD_COLORS), dict(KERNEL_MARKERS)
    for label, g in t.groupby("label", sort=False):
        r = g.iloc[0]
        method = str(r["method"])
        kernel = label[len(method):].rsplit(" ", 1)[0].strip()  # "kernel [h=..dx]" between method and dtype
        if method not in colors:
            colors[method] = SPARE_COLORS[len([m for m in colors if m not in METHOD_COLORS]) % len(SPARE_COLORS)]
        if kernel not in markers:
            markers[kernel] = SPARE_MARKERS[len([k for k in markers if k not in KERNEL_MARKERS]) % len(SPARE_MARKERS)]
        f32 = str(r["dtype"]) == "float32"
        styles[label] = dict(color=colors[method], marker=markers[kernel], mfc="none" if f32 else colors[method],
                             ls="--" if f32 else "-", method=method, kernel=kernel, dtype=str(r["dtype"]))
    return styles


def legend_groups(styles: dict, extra=()) -> list:
    """The legend of run families as (title, handles, labels) groups: method (colour), kernel (marker shape,
    each shown filled and open: the shape alone carries the kernel) and precision (fill, written out
    rather than drawn, so that no legend glyph means two things), `extra` handles (the Pareto front)
    last with the precision."""
    from matplotlib.lines import Line2D

    methods = {st["method"]: st["color"] for st in styles.values()}
    kernels = {st["kernel"]: st["marker"] for st in styles.values()}
    dtypes = {st["dtype"] for st in styles.values()}
    colour = [Line2D([], [], color=c, lw=4, label=m) for m, c in methods.items()]
    shape = [(Line2D([], [], color="0.3", marker=mk, ls="none", ms=6),
              Line2D([], [], color="0.3", marker=mk, mfc="none", ls="none", ms=6)) for mk in kernels.values()]
    shape_labels = [k or "(no kernel)" for k in kernels]
    fill = []
    if len(dtypes) > 1:
        fill = [Line2D([], [], ls="none", label=f"{d}: {how} marker")
                for d, how in (("float64", "filled"), ("float32", "open")) if d in dtypes]
    return [("method / case (colour)", colour, [h.get_label() for h in colour]),
            ("kernel (marker shape)", shape, shape_labels),
            ("precision (fill)" if fill else "", fill + list(extra), [h.get_label() for h in fill + list(extra)])]


def style_legend(ax, styles: dict, extra=()):
    """One legend of methods (colour), kernels (marker) and dtypes (fill) on `ax`."""
    from matplotlib.legend_handler import HandlerTuple

    handles, labels = [], []
    for _, h, lab in legend_groups(styles, extra):
        handles += h
        labels += lab
    ax.legend(handles, labels, fontsize=6, handler_map={tuple: HandlerTuple(ndivide=None, pad=0.3)})


ATLAS_WIDTH_IN = 9.0
"""The atlas's width in inches: at the README's ~800 px a 9-point label is ~11 px tall."""
ATLAS_COLUMNS = 3
LEGEND_FRONT = plt.Line2D([], [], color="k", lw=1, alpha=0.7,
                          label="Pareto front (no run both\nfaster and more accurate)")


def atlas_layout(n: int) -> tuple:
    """(rows, columns) of the atlas's grid of `n` panels."""
    cols = max(1, min(ATLAS_COLUMNS, n))
    return -(-max(1, n) // cols), cols


def log_ticks(ax):
    """Tick labels of a log-log panel that do not run into each other: the decades only (minor ticks
    unlabelled), or 1, 2, 5 x each decade where an axis spans less than about a decade and a half."""
    from matplotlib.ticker import LogFormatterSciNotation, LogLocator, NullFormatter

    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        axis.set_minor_formatter(NullFormatter())
        if lo > 0 and hi > 0 and np.log10(hi / lo) < 1.5:
            axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            axis.set_major_formatter(LogFormatterSciNotation(labelOnlyBase=False, minor_thresholds=(np.inf, np.inf)))


def plot_accuracy(tables: dict, out: Path, formats=("png", "pdf")) -> Path:
    """accuracy.png (and the other `formats`): the atlas's figure (atlas_figure)."""
    fig, _ = atlas_figure(tables)
    return save_figure(fig, out, "accuracy", dpi=150, formats=formats)


def atlas_figure(tables: dict):
    """(figure, panels): one log-log panel per problem with runs (error against wall time), in a grid
    of ATLAS_COLUMNS columns, ATLAS_WIDTH_IN wide; one style per run family across the panels and one
    shared legend in a row of its own below them (nothing drawn over the data or the Pareto front)."""
    from matplotlib.legend_handler import HandlerTuple

    names = [n for n, t in tables.items() if len(t)]
    rows, cols = atlas_layout(len(names))
    styles = family_styles(pd.concat([tables[n] for n in names])) if names else {}
    groups = legend_groups(styles, extra=[LEGEND_FRONT])
    ncols = [2 if len(h) > 4 and j < 2 else 1 for j, (_, h, _) in enumerate(groups)]
    legend_h = 0.6 + 0.25 * max(-(-len(h) // c) for (_, h, _), c in zip(groups, ncols))  # title + rows
    fig = plt.figure(figsize=(ATLAS_WIDTH_IN, 2.75 * rows + legend_h), layout="constrained")
    gs = fig.add_gridspec(rows + 1, cols, height_ratios=[2.75] * rows + [legend_h])
    front, panels = None, []
    for k, name in enumerate(names):
        ax = fig.add_subplot(gs[k // cols, k % cols])
        panels.append(ax)
        t = tables[name]
        for label, g in t.groupby("label"):
            st = styles[label]
            ax.loglog(g["wall_s"], g["error"], st["marker"], color=st["color"], mfc=st["mfc"], ls="none",
                      ms=4.5, mew=0.9, alpha=0.8)
        p = pareto(t)
        front, = ax.loglog(p["wall_s"], p["error"], "k-", lw=1, alpha=0.7, zorder=3)
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("wall time of the run [s]", fontsize=8.5)
        what = PROBLEMS[name][2].replace(" - ", "\u00a0-\u00a0")  # no line break before "- 1"
        ax.set_ylabel(textwrap.fill(what, 30, break_on_hyphens=False), fontsize=8.5)
        ax.tick_params(labelsize=8)
        ax.grid(True, which="both", alpha=0.3)
        log_ticks(ax)
    if not names:
        ax = fig.add_subplot(gs[0, :])
        ax.set(xlabel="wall time of the run [s]", ylabel="error")
        ax.text(0.5, 0.5, "no run records found", ha="center", va="center", transform=ax.transAxes)
    legs = gs[rows, :].subgridspec(1, 3, width_ratios=[1, 1.15, 0.95])
    if front is None:  # no panel: no front in the legend
        groups[2] = (groups[2][0], groups[2][1][:-1], groups[2][2][:-1])
    for j, (title, handles, labels) in enumerate(groups):
        lax = fig.add_subplot(legs[0, j])
        lax.set_axis_off()
        if handles:
            lax.legend(handles, labels, title=title or None, loc="upper center", fontsize=8, title_fontsize=8.5,
                       ncols=ncols[j], frameon=False, borderaxespad=0,
                       handler_map={tuple: HandlerTuple(ndivide=None, pad=0.3)}, columnspacing=1.0,
                       handletextpad=0.5)
    return fig, panels


def plot_convergence(tables: dict, out: Path) -> dict:
    """Error vs dx and wall time vs N per problem and label; returns {problem: {label: (order, exponent)}}."""
    names = [n for n, t in tables.items() if len(t) and n != "gradients"]
    fig, axes = plt.subplots(2, max(1, len(names)), figsize=(4.6 * max(1, len(names)), 7.5), squeeze=False,
                             constrained_layout=True)
    fits = {}
    for j, name in enumerate(names):
        t = tables[name]
        styles = family_styles(t)
        fits[name] = {}
        for label, g in t.groupby("label"):
            order = fitted_order(g["dx"], g["error"])
            expo = fitted_order(g["n_particles"], g["wall_s"])
            fits[name][label] = (order, expo)
            g = g.sort_values("dx")
            st = styles[label]
            kw = dict(color=st["color"], marker=st["marker"], mfc=st["mfc"], ls=st["ls"], ms=4, lw=1, alpha=0.8)
            axes[0, j].loglog(g["dx"], g["error"], **kw)
            axes[1, j].loglog(g["n_particles"], g["wall_s"], **kw)
        axes[0, j].set(title=f"{name} (orders: accuracy.md)", xlabel="dx", ylabel="error")
        axes[1, j].set(xlabel="particles N", ylabel="wall time [s]")
        for ax in axes[:, j]:
            ax.grid(True, which="both", alpha=0.3)
            style_legend(ax, styles)
    fig.savefig(out / "convergence.png", dpi=130)
    plt.close(fig)
    return fits


def write_md(atlas, tables: dict, fits: dict, out: Path):
    lines = ["# Accuracy-cost atlas", "",
             "Cheapest run (wall time of the solve, compilation excluded) that reaches each error level, "
             "per problem; `-` where no run of the atlas reaches it.", ""]
    for name, t in tables.items():
        lines += [f"## {name}", "", f"error: {PROBLEMS[name][2]}; {len(t)} runs", ""]
        if not len(t):
            lines += ["no run records found (run its experiment first)", ""]
            continue
        lines += [timing_line(t), "",
                  "| error level | cheapest run | dx | particles | error | wall time [s] | other work meanwhile [cores] |",
                  "|---|---|---|---|---|---|---|"]
        for lv in atlas.levels:
            ok = t[t["error"] <= lv]
            if ok.empty:
                lines.append(f"| {lv:g} | - | | | | | |")
                continue
            r = ok.loc[ok["wall_s"].idxmin()]
            lines.append(f"| {lv:g} | {r['label']} | {r['dx']:g} | {int(r['n_particles'])} | {r['error']:.3g} | "
                         f"{r['wall_s']:.3g} | {other_load.cell(r.get('other_load'))} |")
        if name in fits:
            lines += ["", "| run family | observed order in dx | wall time ~ N^k |", "|---|---|---|"]
            for label, (o, e) in sorted(fits[name].items()):
                lines.append(f"| {label} | {o:.2f} | {e:.2f} |")
        lines.append("")
    lines += checkpointing_lines(out.parent.parent / "bench" / "grad_memory.csv")
    (out / "accuracy.md").write_text("\n".join(lines) + "\n")


BUSY_CORES = 0.25
"""Other work above this many cores (on average) marks a run as timed beside other work."""


def timing_line(t: pd.DataFrame) -> str:
    """How the problem's runs were timed: how many beside other work (lab.other_load), how
    many without a measurement (records made before it was recorded)."""
    load = pd.to_numeric(t["other_load"], errors="coerce") if "other_load" in t else pd.Series(np.nan, index=t.index)
    known = load.dropna()
    busy = known[known > BUSY_CORES]
    parts = [f"timed alone (other work <= {BUSY_CORES:g} cores on average): {len(known) - len(busy)} runs"]
    if len(busy):
        parts.append(f"beside other work: {len(busy)} runs ({busy.min():.2g}-{busy.max():.2g} cores; their wall "
                     "times overstate this machine's)")
    if len(t) - len(known):
        parts.append(f"not measured: {len(t) - len(known)} runs")
    return "Timing: " + "; ".join(parts) + "."


def checkpointing_lines(csv: Path) -> list:
    """accuracy.md's section on what gradient checkpointing costs, from bench/bench_grad_memory.py's
    table (results/bench/grad_memory.csv: the gradient of E_kin after n steps of a 2D TGV w.r.t. the
    initial positions, plain reverse mode / sqrt(n) segments / nested). Checkpointing recomputes the
    same forward steps, so it buys memory with time at no cost in accuracy: tests/core/test_gradients.py
    checks equal gradients to round-off; here the gradient norms of the strategies are compared."""
    lines = ["## Gradients through long rollouts: what checkpointing costs", ""]
    note_input(csv)
    if not csv.exists():
        return lines + [f"no table {csv} (run `python bench/bench_grad_memory.py`)", ""]
    t = pd.read_csv(csv)
    lines += ["Same gradient, different memory and time (`bench/bench_grad_memory.py`; rss = peak resident "
              "memory above the process's before the gradient, est = XLA's own estimate; the last column "
              "compares the gradient's norm with the plain one where both ran).", "",
              "| dtype | steps | checkpointing | segments | gradient [s] | other load [cores] | rss [GB] | est [GB] | "
              "norm / plain - 1 | status |", "|---|---|---|---|---|---|---|---|---|---|"]
    for _, r in t.iterrows():
        plain = t[(t["dtype"] == r["dtype"]) & (t["steps"] == r["steps"]) & (t["checkpoint"] == "none")]
        dev = "-"
        if len(plain) and np.isfinite(plain["grad_norm"].iloc[0]) and np.isfinite(r.get("grad_norm", np.nan)):
            dev = f"{r['grad_norm'] / plain['grad_norm'].iloc[0] - 1:.1e}"
        fmt = lambda k, f: (f.format(r[k]) if k in r and pd.notna(r[k]) else "-")  # noqa: E731
        load = other_load.cell(r.get("other_load"))
        lines.append(f"| {r['dtype']} | {int(r['steps'])} | {r['checkpoint']} | {fmt('segments', '{:.0f}')} | "
                     f"{fmt('run_s', '{:.3g}')} | {load if pd.notna(r.get('run_s')) else '-'} | {fmt('rss_GB', '{:.3g}')} | "
                     f"{fmt('est_GB', '{:.3g}')} | {dev} | "
                     f"{r.get('status', '')} |")
    return lines + [""]


def build(atlas, results, out=None) -> Path:
    """Every output of the atlas into `out` (default <results>/accuracy) from the records below `results`."""
    out = Path(out) if out is not None else Path(results) / HERE.name
    out.mkdir(parents=True, exist_ok=True)
    runs = gather(atlas, results)
    runs.to_csv(out / "runs.csv", index=False)
    tables = {name: problem_table(runs, atlas, name) for name in PROBLEMS}
    plot_accuracy(tables, out)
    fits = plot_convergence(tables, out)
    write_md(atlas, tables, fits, out)
    print(f"accuracy: {len(runs)} run records -> {out}/runs.csv, accuracy.png, convergence.png, accuracy.md")
    return out


def replot(runs_csv, profile: str = "paper", out=None, formats=("png",)) -> Path:
    """Re-draw accuracy.png from a runs.csv the atlas wrote (e.g. a snapshot's
    docs/results/paper/accuracy/runs.csv), without the records or experiments behind it: the same
    tables (problem_table) and plot as `build`. Writes into `out` (default: beside runs.csv)."""
    runs_csv = Path(runs_csv)
    atlas = load_settings(HERE, profile)
    runs = pd.read_csv(runs_csv)
    tables = {name: problem_table(runs, atlas, name) for name in PROBLEMS}
    out = Path(out) if out is not None else runs_csv.parent
    out.mkdir(parents=True, exist_ok=True)
    png = plot_accuracy(tables, out, formats=formats)
    print(f"accuracy: {len(runs)} rows of {runs_csv} -> {png}")
    return png


def plot(exp, out) -> Path:
    """The atlas of the experiment's profile (lab.experiment.plot_main): every output into `out`."""
    build(exp.settings, exp.results, out)
    return Path(out) / "accuracy.png"


if __name__ == "__main__":
    import sys

    if "--from-runs" in sys.argv:  # re-plot accuracy.png only, from an existing runs.csv
        import argparse

        ap = argparse.ArgumentParser(description=replot.__doc__)
        ap.add_argument("--from-runs", required=True, help="a runs.csv written by the atlas")
        ap.add_argument("--profile", default="paper", help="the atlas profile (its TGV error column)")
        ap.add_argument("--out", default=None, help="folder for accuracy.png (default: beside runs.csv)")
        a = ap.parse_args()
        replot(a.from_runs, a.profile, a.out)
    else:
        plot_main(plot, __file__, __doc__)
