"""README tables of the gradient experiments (Figs. 1-2), generated from the snapshot's metrics
tables by `make readme-tables` (report/readme_tables.py registers it):

    gradients  Fig. 1: AD against central finite differences, relative L2 error per case and dtype
               (fig1/metrics.csv); Fig. 2: final-position RMSE of the inverse problem per optimizer
               from both starts, the paper's text's random one and the authors' notebook's displaced
               one, beside the notebook's printed RMSE (the only published one; fig2/summary.csv)
    gradcheck  Fig. 1 in full (gradcheck/README.md): per case and dtype the relative L2 error, max
               abs error and MSE of AD against FD, and the time of each
    inverse    Fig. 2 in full (inverse/README.md): per case and start (displaced, random) the final
               RMSE of every optimizer, bold below the paper's; a diverged one with its best iterate

Every number is a cell of those files; nothing is typed by hand."""
from pathlib import Path

import pandas as pd

from .readme_cells import SourceMissing, find_source, sci

CASES = {"tgv": "Taylor-Green vortex", "ldc": "lid-driven cavity (moving lid, no-slip walls)"}
OPTIMIZERS = {"gd": "GD on the MSE", "adam": "Adam", "gd_rmse": "GD on the RMSE (the paper's)"}
STARTS = {"random": "random start (the paper's text)", "displaced": "displaced start (the authors' notebook)"}
BOTH_OPTIMIZERS = {**OPTIMIZERS, "gd_rmse": "GD on the RMSE (the notebook's)"}


def gradients(snapshot: Path) -> list:
    lines = []
    try:
        g = pd.read_csv(find_source(snapshot, "fig1/metrics.csv"))
    except SourceMissing:
        g = None
    if g is not None:
        lines += ["| Fig. 1: AD against central FD | float64 rel. L2 | float32 rel. L2 | AD s per gradient (float64) |",
                  "|---|---|---|---|"]
        for case, t in g.groupby("case", sort=False):
            by = t.set_index("dtype")
            cell = {d: sci(by.loc[d, "rel_l2"]) if d in by.index else "-" for d in ("float64", "float32")}
            ad_s = f"{float(by.loc['float64', 'ad_s']):.2g}" if "float64" in by.index else "-"
            lines.append(f"| {CASES.get(case, case)}, {int(t['n_fluid'].iloc[0])} fluid particles | {cell['float64']} | "
                         f"{cell['float32']} | {ad_s} |")
    try:
        inv = pd.read_csv(find_source(snapshot, "fig2/summary.csv"))
    except SourceMissing:
        inv = None
    if inv is not None:
        opts = [o for o in BOTH_OPTIMIZERS if o in set(inv["optimizer"])]
        lines += ([""] if lines else []) + [
            f"| Fig. 2: final-position RMSE after {int(inv['iterations'].iloc[0])} updates | "
            + " | ".join(BOTH_OPTIMIZERS[o] for o in opts) + " | the notebook's (displaced start) | s per update |",
            "|---|" + "---|" * (len(opts) + 2)]
        for case, c in inv.groupby("case", sort=True):
            for start in [s for s in STARTS if s in set(c["start"])]:
                t = c[c["start"] == start]
                by = t.set_index("optimizer")
                cells = ["diverged" if bool(by.loc[o, "diverged"]) else sci(by.loc[o, "rmse_final"]) if o in by.index
                         else "-" for o in opts]
                lines.append(f"| case {case}, {STARTS[start]} | " + " | ".join(cells) +
                             f" | {float(t['paper_rmse_final'].iloc[0]):g} | "
                             f"{t['wall_s_per_iteration'].min():.2g}-{t['wall_s_per_iteration'].max():.2g} |")
    if not lines:
        raise SourceMissing("fig1/metrics.csv and fig2/summary.csv are not in the snapshot")
    return lines


def gradcheck(snapshot: Path) -> list:
    g = pd.read_csv(find_source(snapshot, "fig1/metrics.csv"))
    lines = ["| case | dtype | rel. L2 error AD vs FD | max abs error | MSE(AD - FD) | AD time | FD time |",
             "|---|---|---|---|---|---|---|"]
    for _, r in g.iterrows():
        lines.append(f"| {CASES.get(r['case'], r['case'])} | {r['dtype']} | {sci(r['rel_l2'])} | {sci(r['max_abs'])} | "
                     f"{sci(r['mse'])} | {float(r['ad_s']):.2g} s | {float(r['fd_s']):.2g} s |")
    return lines


def inverse(snapshot: Path) -> list:
    inv = pd.read_csv(find_source(snapshot, "fig2/summary.csv"))
    opts = [o for o in OPTIMIZERS if o in set(inv["optimizer"])]
    lines = ["| case | start (its RMSE) | " + " | ".join(f"{OPTIMIZERS[o]}" for o in opts) + " | paper |",
             "|---|---|" + "---|" * (len(opts) + 1)]
    for (case, start), t in inv.groupby(["case", "start"], sort=False):
        by = t.set_index("optimizer")

        def cell(o):
            r = by.loc[o]
            if bool(r["diverged"]):
                return f"diverged (best {sci(r['best_rmse_final'])})"
            v = sci(r["rmse_final"])
            return f"**{v}**" if float(r["rmse_final"]) < float(r["paper_rmse_final"]) else v
        start_rmse = float(t["loss_initial"].iloc[0]) ** 0.5  # the loss is the MSE of the positions
        lines.append(f"| {case} | {start} ({start_rmse:.2f}) | " + " | ".join(cell(o) for o in opts) +
                     f" | {float(t['paper_rmse_final'].iloc[0]):g} |")
    return lines
