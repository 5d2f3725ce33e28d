"""`make snapshot [PROFILE=paper]`: a finished report with its figures (compressed PNGs), metrics
tables and run records, copied into docs/results/<profile>/ with its provenance, small enough to
commit (<= 10 MB in all; checked). A target the committed snapshot holds and the results do not (a
fresh clone that ran one target) is never dropped silently: the snapshot refuses, naming it, until
`make restore` has seeded results/ from the committed snapshot (or DROP=1 says to drop it).

A snapshot records the commit it was made at, so it refuses a working tree with uncommitted changes
to tracked files (naming them): commit first. `--allow-dirty` (`make snapshot DIRTY=1`) makes it
anyway and marks every file as made from that tree: provenance.json gets `dirty_tree: true`, the
changed paths and the list of every file of the snapshot, and the README's generated provenance line
says so.

    python -m report.snapshot --profile paper [--results results/paper] [--out docs/results/paper] [--allow-dirty]

What is copied, keeping the paths below results/<profile>/: the figures named in
docs/paper_values.yaml (as palette PNGs at most 1400 px wide), every csv / md table of a target
folder (results/<profile>/<folder>/*.{csv,md}), every record.json (any depth) below a folder that
has such a table (an experiment still running, e.g. the atlas's sweep before it gathers, has none:
its records would be a partial set), the SitL runs' training, evaluation and dataset records
(`sitl_records`: enough for `make restore` to bring a finished training back as current) and the report's provenance.json. Targets shown from a fallback profile (Table 1 / Fig. 3 from `cpu`) are copied
into docs/results/<fallback>/ the same way. The report is then rebuilt from the copy, so that each
number on the snapshot's page traces to a file of the snapshot."""
import argparse
import datetime
import json
import os
import shutil
import sys
from pathlib import Path

from . import build, figures, model, paper, provenance

LIMIT_MB = 10.0


def _copy(src: Path, dst: Path) -> None:
    dst.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, dst)


def copy_results(src: Path, dst: Path, figure_paths) -> int:
    """Tables, records and (compressed) figures of `src` into `dst`; returns the number of files."""
    n = 0
    for f in sorted(src.glob("*/*")):
        if f.is_file() and f.suffix in (".csv", ".md") and f.parent.name != "report":
            _copy(f, dst / f.relative_to(src))
            n += 1
    for f in sorted(src.rglob("record.json")):
        if not any((src / f.relative_to(src).parts[0]).glob("*.csv")):
            continue  # an experiment still running (no table written yet): its records are partial
        _copy(f, dst / f.relative_to(src))
        n += 1
    for f in sitl_records(src):
        _copy(f, dst / f.relative_to(src))
        n += 1
    for rel in figure_paths:
        f = src / rel
        if f.exists():
            figures.compress_png(f, dst / rel) if f.suffix == ".png" else _copy(f, dst / rel)
            n += 1
    return n


SITL_RECORDS = ("train.json", "curve.jsonl", "generate.json", "budget.json", "authors_force.json")


def sitl_records(src: Path) -> list:
    """The SitL runs' own records, so that a restored run is current without its checkpoint
    (sitl/study.py `stored_row`): each training's train.json and learning curve, each evaluation's metrics/<model>.json,
    each dataset's generate.json / metadata.json, the equal-cost budget, the authors'-force result;
    below sitl/ (Table 1's runs, once Table 1 or the study has written its table) and sitl_study/,
    never through a run's link to the shared dataset. Checkpoints, rollouts and data stay out, and so
    do the set-aside folders of runs trained on other inputs or damaged (`<name>.stale-<n>`) and the
    train.json of a training still under way (not `complete`: restored without its checkpoints, it
    would describe nothing)."""
    if not (any((src / "table1").glob("*.csv")) or any((src / "sitl_study").glob("*.csv"))):
        return []
    out = []
    for top in ("sitl", "sitl_study"):
        for root, dirs, names in os.walk(src / top):  # os.walk does not follow links to folders
            dirs[:] = [d for d in dirs if ".stale-" not in d]
            for name in names:
                if name == "train.json" and not finished_training(Path(root) / name):
                    continue
                if name in SITL_RECORDS or (Path(root).name == "metrics" and name.endswith(".json")) \
                        or (name == "metadata.json" and "generate.json" in names):
                    out.append(Path(root) / name)
    return sorted(out)


def finished_training(path: Path) -> bool:
    """A train.json that records a finished training (sitl/train.py sets `complete` at the end)."""
    try:
        record = json.loads(path.read_text())
    except (OSError, ValueError):
        return False
    return isinstance(record, dict) and record.get("complete") is True


BENCH_SUFFIXES = (".csv", ".md", ".json")


def copy_bench(src: Path, dst: Path) -> list:
    """The benchmarks' tables (results/bench/*.{csv,md,json}, written by bench/*.py: timings and
    memory the README quotes) into the snapshot's bench/ folder (docs/results/bench), so that a number
    quoted from them survives the loss of results/. A table the snapshot holds and results/bench lacks
    is kept (a benchmark is run by hand, one at a time); one that results/bench holds replaces it.
    Returns the names copied."""
    names = sorted(f.name for f in Path(src).glob("*") if f.is_file() and f.suffix in BENCH_SUFFIXES) \
        if Path(src).is_dir() else []
    for n in names:
        _copy(Path(src) / n, Path(dst) / n)
    return names


def size_mb(*folders) -> float:
    return sum(p.stat().st_size for d in folders if Path(d).exists() for p in Path(d).rglob("*") if p.is_file()) / 2**20


def largest(*folders, k: int = 8) -> list:
    files = [p for d in folders if Path(d).exists() for p in Path(d).rglob("*") if p.is_file()]
    return sorted(files, key=lambda p: -p.stat().st_size)[:k]


def folders(d: Path) -> list:
    """The target folders of a snapshot or results folder that hold files (its report excepted: it is
    rebuilt, never restored or compared)."""
    return sorted(p.name for p in Path(d).iterdir() if p.is_dir() and p.name != "report"
                  and any(f.is_file() for f in p.rglob("*"))) if Path(d).is_dir() else []


def dropped(groups) -> list:
    """The folders a snapshot already holds (dst) whose results (src) have none: what it would lose."""
    have = {src: set(folders(src)) for src, _ in groups}
    return [f"{dst.name}/{n}" for src, dst in groups for n in folders(dst) if n not in have[src]]


class DirtyTree(RuntimeError):
    """The working tree has uncommitted changes to tracked files: a snapshot would name a commit whose
    files it was not made from."""


def snapshot(profile: str, results, out, drop: bool = False, allow_dirty: bool = False) -> Path:
    """Replace the snapshot in `out` by the finished report of `results`; refuses (RuntimeError, naming
    them) to drop a folder the snapshot holds and the results lack, unless `drop`, and (DirtyTree) a
    working tree with uncommitted changes, unless `allow_dirty`, which marks every file as made from it."""
    results, out = Path(results).resolve(), Path(out).resolve()
    page = results / "report" / "index.html"
    if not page.exists():
        raise FileNotFoundError(f"{page}: no finished report; run `make report PROFILE={profile}` first")
    changed = provenance.dirty_paths()  # before the copy below rewrites tracked files of docs/results
    if changed and not allow_dirty:
        shown = ", ".join(changed[:8]) + (f" and {len(changed) - 8} more" if len(changed) > 8 else "")
        raise DirtyTree(f"the working tree has uncommitted changes ({shown}): commit them first, so that the "
                        f"snapshot names the commit it was made from, or DIRTY=1 (--allow-dirty) to mark every "
                        f"file of the snapshot as made from a dirty tree")
    made_at = provenance.commit()
    entries = paper.targets()
    rep = model.build(results, profile)
    groups = {}  # (source folder, destination folder) -> figure paths
    profiles = {out: profile}  # destination folder -> the profile its runs were made in
    for t in rep.targets:
        src = results.parent / t.profile if t.fallback else results
        dst = out.parent / t.profile if t.fallback else out
        profiles[dst] = t.profile
        groups.setdefault((src, dst), []).extend(entries[t.name].get("figures") or [])
    lost = [] if drop else dropped(groups)
    if lost:
        raise RuntimeError(f"the results have no {', '.join(lost)}, which the snapshot in {out.parent} holds: "
                           f"`make restore PROFILE={profile}` first keeps them (then `make report`), "
                           f"or DROP=1 drops them")
    for _, dst in groups:
        if dst.exists():
            shutil.rmtree(dst)
    n = sum(copy_results(src, dst, figs) for (src, dst), figs in groups.items())
    bench = copy_bench(results.parent / "bench", out.parent / "bench")
    prov = json.loads((results / "report" / provenance.FILE).read_text()) \
        if (results / "report" / provenance.FILE).exists() else provenance.collect(profile)
    prov.update({"snapshot_date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
                 "snapshot_commit": made_at})
    for key in ("dirty_tree", "dirty_paths", "dirty_files"):
        prov.pop(key, None)  # a report's own provenance never carries an older snapshot's marks
    for _, dst in groups:
        own = dict(prov, profile=profiles[dst]) if profiles[dst] == profile else \
            dict(prov, profile=profiles[dst], shown_in=f"the {profile} report")
        if changed:  # --allow-dirty: every file of this folder named as made from the dirty tree
            files = [str(f.relative_to(dst)) for f in dst.rglob("*") if f.is_file()] + [provenance.FILE]
            if dst == out:  # the report rebuilt below, and the benchmark tables copied beside
                files += [f"report/{n}" for n in ("index.html", "report.md", provenance.FILE)] + \
                    [f"../bench/{n}" for n in bench]
            own.update({"dirty_tree": True, "dirty_paths": changed, "dirty_files": sorted(set(files))})
        (dst / provenance.FILE).write_text(json.dumps(own, indent=2) + "\n")
    build.write(model.build(out, profile), out / "report", copy_figures=False)
    total = size_mb(*{d for _, d in groups}, out.parent / "bench")
    print(f"snapshot -> {out}: {n} files, {total:.2f} MB; {len(bench)} benchmark tables -> {out.parent / 'bench'}",
          flush=True)
    if total > LIMIT_MB:
        big = ", ".join(f"{p.relative_to(out.parent)} ({p.stat().st_size / 2**20:.2f} MB)"
                        for p in largest(*{d for _, d in groups}, out.parent / "bench"))
        raise RuntimeError(f"snapshot is {total:.1f} MB, above the {LIMIT_MB:g} MB limit; largest: {big}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None)
    ap.add_argument("--out", default=None)
    ap.add_argument("--drop", action="store_true", help="allow the new snapshot to lack targets the old one holds")
    ap.add_argument("--allow-dirty", action="store_true",
                    help="snapshot a working tree with uncommitted changes, marking every file as made from it")
    a = ap.parse_args(argv)
    try:
        snapshot(a.profile, a.results or f"results/{a.profile}", a.out or f"docs/results/{a.profile}", a.drop,
                 a.allow_dirty)
    except (FileNotFoundError, RuntimeError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
