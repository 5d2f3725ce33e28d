"""`make readme-tables`: the README's result tables, generated from the committed snapshot's
records (docs/results/<profile>/), between marker comments:

    <!-- table:NAME -->
    ...generated...
    <!-- /table:NAME -->

    python -m report.readme_tables --snapshot docs/results/paper [--readme README.md ...] [--check]

Tables (`tables`): `tgv2d` (Figs. 4-5, fig5/metrics.csv), `table1` (Table 1, table1/table1.csv),
`atlas` (the cheapest setting per error level, accuracy/runs.csv), `figures` (the key figures
with one sentence each, `readme_caption` in docs/paper_values.yaml), `cavity`, `dambreak`, `heat`
(Figs. 6-8, 10: report/readme_walls.py), `gradients` (Figs. 1-2: report/readme_gradients.py),
`fig9` (report/readme_tgv3d.py), `stability` (report/readme_stability.py), `verdicts` and
`provenance` (the report's verdicts, the snapshot's commit and date: report/readme_verdicts.py), `sitl_study`,
`sitl_table1` and `sitl_cost` (Solver-in-the-Loop, report/readme_sitl.py); these modules build
on this one's helpers. `make readme-tables` regenerates every page of `READMES` (the top-level
README, the topic pages of docs/ and the experiments' READMEs, which show the same generated tables).
Only marked tables are touched; an unknown marker or a missing snapshot is an error; a table whose
target is not in the snapshot yet says so (no number). Table 1 and Fig. 3 are taken from the
sibling `cpu` snapshot when the paper one has none (labelled); Table 1 shows each mean with its
interval and the paired comparisons. --check changes nothing and exits 1 when
the README differs from what the snapshot gives (tests/experiments/test_report.py)."""
import argparse
import difflib
import os
import re
import sys
from pathlib import Path

import pandas as pd

from sitl.fmt import ratio_digits
from lab import other_load

from . import atlas, paper
from .readme_cells import METHODS, SourceMissing, find_source, pct, sci, snapshot_csv

MARKER = re.compile(r"(<!-- table:(?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /table:(?P=name) -->)", re.S)
NAMES = {"solver": "solver only", "gns": "GNS", "sitl": "SitL"}


def tgv2d(snapshot: Path) -> list:
    t = snapshot_csv(snapshot, "fig5/metrics.csv")
    order = {m: i for i, m in enumerate(METHODS)}
    t = t.assign(_m=t["method"].map(order).fillna(99)).sort_values(["_m", "dx"], ascending=[True, False])
    lines = ["| method | dx | u_max error t = 1 | t = 2 | time-averaged u_max / E_kin error | ms per step |",
             "|---|---|---|---|---|---|"]
    for _, r in t.iterrows():
        lines.append(f"| {METHODS.get(r['method'], r['method'])} | {r['dx']:g} | {pct(r.get('u_max_relerr_t1'))} | "
                     f"{pct(r.get('u_max_relerr_t2'))} | {pct(r['u_max_relerr_mean'])} / {pct(r['e_kin_relerr_mean'])} | "
                     f"{float(r['ms_per_step']):.3g} |")
    return lines


def table1(snapshot: Path) -> list:
    src = find_source(snapshot, "table1/table1.csv", fallback=True)
    t = pd.read_csv(src).set_index("metric")
    note = [] if src.is_relative_to(snapshot) else \
        [f"_Profile `{src.parents[1].name}` ({src.parents[1].name}/table1/table1.csv of the snapshot): the paper "
         "profile needs a GPU._", ""]
    models = [m for m in ("solver", "gns", "sitl") if f"{m}_ours" in t]
    spread = all(f"{m}_lo" in t and f"{m}_hi" in t for m in models)
    ours_head = "ours [95 % interval] / paper" if spread else "ours / paper"
    lines = note + ["| metric | " + " | ".join(f"{NAMES[m]} ({ours_head})" for m in models) + " |",
                    "|---|" + "---|" * len(models)]
    for metric in ("MSE_5", "MSE_20", "MSE_Ekin", "Sinkhorn"):
        if metric not in t.index:
            continue
        ours = {m: pd.to_numeric(t.loc[metric, f"{m}_ours"], errors="coerce") for m in models}
        best = min((v for v in ours.values() if pd.notna(v)), default=None)

        def cell(m):
            v = f"**{sci(ours[m])}**" if ours[m] == best else sci(ours[m])
            if spread and pd.notna(t.loc[metric, f"{m}_lo"]):
                v += f" [{sci(t.loc[metric, f'{m}_lo'])}, {sci(t.loc[metric, f'{m}_hi'])}]"
            return f"{v} / {sci(t.loc[metric, f'{m}_paper'])}"
        lines.append(f"| {metric} | " + " | ".join(cell(m) for m in models) + " |")
    if "inference s / coarse step" in t.index:
        ms = [1e3 * float(t.loc["inference s / coarse step", f"{m}_ours"]) for m in models]
        lines.append("| ms per coarse step | " + " | ".join(f"{v:.2g}" if v < 100 else f"{v:.0f}" for v in ms) + " |")
    if "training steps" in t.index and "training wall s" in t.index:
        cells = []
        for m in models:
            steps, wall = t.loc["training steps", f"{m}_ours"], t.loc["training wall s", f"{m}_ours"]
            ok = pd.notna(pd.to_numeric(steps, errors="coerce")) and m != "solver"
            cells.append(f"{int(float(steps))} steps, {float(wall):.0f} s" if ok else "")
        lines.append("| training | " + " | ".join(cells) + " |")
    if spread and "test windows" in t.index:
        n = pd.to_numeric(t.loc["test windows", f"{models[0]}_ours"], errors="coerce")
        if pd.notna(n):
            lines += ["", f"Ours: the mean over {int(n)} test windows of every seed, with its 95 % bootstrap interval "
                          "over the windows."]
    return lines + table1_comparisons(src.with_name("comparisons.csv"))


def table1_comparisons(src: Path) -> list:
    """The paired comparisons beside table1.csv (sitl/table1.py's comparisons.csv: ratio of means on
    the same test windows with its paired bootstrap interval), MSE_20 and MSE_Ekin; [] when absent."""
    if not src.exists():
        return []
    c = pd.read_csv(src)
    c = c[c["metric"].isin(["MSE_20", "MSE_Ekin"])]
    if c.empty:
        return []
    lines = ["", "Paired on the same test windows (ratio of the means, 95 % paired bootstrap interval):", "",
             "| a / b | metric | ratio | a is |", "|---|---|---|---|"]
    for _, r in c.iterrows():
        ratio, lo, hi = float(r["ratio"]), float(r["lo"]), float(r["hi"])
        d = ratio_digits(ratio, lo, hi)
        lines.append(f"| {NAMES[r['a']]} / {NAMES[r['b']]} | {r['metric']} | {ratio:.{d}g} "
                     f"[{lo:.{d}g}, {hi:.{d}g}] | {r['verdict']} |")
    return lines


def atlas_table(snapshot: Path, profile: str) -> list:
    runs = find_source(snapshot, "accuracy/runs.csv")
    lines = ["| error you accept | cheapest setting that reaches it | wall time of the run | other work meanwhile "
             "[cores] |", "|---|---|---|---|"]
    for r in atlas.cheapest(runs, profile):
        if r.run is None:
            lines.append(f"| {100 * r.level:g} % | no run | - | - |")
            continue
        setting = f"{atlas.setting_label(r.run)}, dx {r.run['dx']:g} ({int(r.run['n_particles'])} particles)"
        load = other_load.cell(r.traces["other_load"].value() if "other_load" in r.traces else None)
        if r.reached:
            lines.append(f"| {100 * r.level:g} % | {setting} | {float(r.run['wall_s']):.2g} s | {load} |")
        else:
            lines.append(f"| {100 * r.level:g} % | no setting of the sweep (best: {setting}: {pct(r.run['error'], 2)}, "
                         f"{float(r.run['wall_s']):.2g} s) | - | {load} |")
    return lines + ["", atlas.OTHER_LOAD_NOTE]


def figures(snapshot: Path, readme: Path) -> list:
    lines = []
    for name, entry in paper.targets().items():
        cap = entry.get("readme_caption")
        figs = []
        for f in entry.get("figures") or []:
            try:
                figs.append(find_source(snapshot, f, fallback=bool(entry.get("fallback"))))
            except SourceMissing:
                pass
        if not cap or not figs:
            continue
        src = figs[0]
        prof = "" if src.is_relative_to(snapshot) else f", profile `{src.relative_to(snapshot.parent).parts[0]}`"
        link = os.path.relpath(src, readme.parent)
        lines += [f"**{entry['paper']['where']}** ({name}{prof}): {cap}", "", f"![{name}]({link})", ""]
    if not lines:
        raise SourceMissing(f"{snapshot}: no figure of the snapshot has a readme_caption")
    return lines[:-1]


def tables(snapshot: Path, readme: Path, profile: str) -> dict:
    from . import readme_gradients as G, readme_sitl as Si, readme_stability as St, readme_tgv3d as T3
    from . import readme_verdicts as V, readme_walls as W

    return {"tgv2d": lambda: tgv2d(snapshot), "table1": lambda: table1(snapshot),
            "atlas": lambda: atlas_table(snapshot, profile), "figures": lambda: figures(snapshot, readme),
            "cavity": lambda: W.cavity(snapshot), "dambreak": lambda: W.dambreak(snapshot),
            "heat": lambda: W.heat(snapshot), "gradients": lambda: G.gradients(snapshot),
            "gradcheck": lambda: G.gradcheck(snapshot), "inverse": lambda: G.inverse(snapshot),
            "fig9": lambda: T3.fig9(snapshot), "stability": lambda: St.stability(snapshot),
            "verdicts": lambda: V.verdicts(snapshot, readme, profile), "provenance": lambda: V.provenance(snapshot),
            **Si.tables(snapshot)}


def regenerate(text: str, snapshot: Path, readme: Path, profile: str = None) -> str:
    """`text` with every marked table replaced by the one the snapshot gives."""
    gens = tables(Path(snapshot), Path(readme), profile or Path(snapshot).name)

    def sub(m):
        name = m.group("name")
        if name not in gens:
            raise KeyError(f"{readme}: unknown table marker {name!r} (known: {', '.join(gens)})")
        try:
            lines = gens[name]()
        except SourceMissing as e:
            if not Path(snapshot).is_dir():
                raise
            # a snapshot made before every target ran: the table says so, with no number
            lines = [f"_Not in this snapshot yet ({e}): the target has not been run for it; "
                     "`make all`, then `make snapshot readme-tables`._"]
        return m.group(1) + "\n".join(lines) + "\n" + m.group(4)

    return MARKER.sub(sub, text)


def markers(text: str) -> list:
    return [m.group("name") for m in MARKER.finditer(text)]


READMES = ("README.md", "docs/results.md", "sitl/README.md", "experiments/tgv2d/README.md", "experiments/tgv3d/README.md",
           "experiments/ldc2d/README.md", "experiments/dambreak2d/README.md", "experiments/thermal/README.md",
           "experiments/stability/README.md", "experiments/accuracy/README.md", "gradcheck/README.md",
           "inverse/README.md")
"""The pages (relative to the repository root) whose marked tables `make readme-tables` regenerates
and tests/experiments/test_report.py checks against the committed snapshot: the README, the topic
pages of docs/ and the experiments' READMEs."""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--snapshot", default="docs/results/paper")
    ap.add_argument("--readme", nargs="+", default=None, help="default: every README of READMES")
    ap.add_argument("--profile", default=None, help="the atlas config's profile (default: the snapshot folder's name)")
    ap.add_argument("--check", action="store_true")
    a = ap.parse_args(argv)
    rc = 0
    for name in a.readme or [str(paper.ROOT / r) for r in READMES]:
        rc = max(rc, one(Path(name), Path(a.snapshot), a.profile, a.check))
    return rc


def one(readme: Path, snapshot: Path, profile, check: bool) -> int:
    """Regenerate (or --check) one README; 0 done / matches, 1 differs (check), 2 error."""
    old = readme.read_text()
    try:
        new = regenerate(old, snapshot, readme, profile)
    except (SourceMissing, KeyError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if check:
        if new != old:
            sys.stdout.writelines(difflib.unified_diff(old.splitlines(True), new.splitlines(True), str(readme), "generated"))
            return 1
        print(f"{readme}: tables {', '.join(markers(old)) or '(none)'} match {snapshot}")
        return 0
    if new != old:
        readme.write_text(new)
    print(f"{readme}: tables {', '.join(markers(old)) or '(none)'} {'regenerated' if new != old else 'unchanged'} from {snapshot}")
    return 0


if __name__ == "__main__":
    # run as the package's module, not __main__: the table modules import report.readme_tables, and
    # its SourceMissing must be the class that `regenerate` catches
    from report import readme_tables

    sys.exit(readme_tables.main())
