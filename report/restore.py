"""`make restore [PROFILE=paper]`: seed results/<profile>/ from the committed snapshot
docs/results/<profile>/ (and the snapshots of the fallback profiles its report shows, e.g.
docs/results/cpu for Table 1), so that a fresh clone, or a machine whose results/ was lost, keeps
every target the snapshot holds: `make report` shows them, `make accuracy` gathers their records,
and `make snapshot` after a partial re-run does not drop them (it refuses to, see report/snapshot.py).

    python -m report.restore --profile paper [--snapshot docs/results/paper] [--results results/paper]

What is restored is the snapshot as committed: tables, run records and compressed figures, not the
trajectories. A target folder is copied whole and only when results/<profile>/ has no such folder
(or an empty one): a target run here is never mixed with, or overwritten by, the snapshot's. The
snapshot's provenance.json and report/ are not copied (the report is rebuilt, with this machine's
provenance); `restored.json` in results/<profile>/ names the snapshot (commit, date), the folders
taken from it with the snapshot each was first made for (one restored into the snapshot restored from
keeps its earlier origin) and the digest of every file it copied, and the report's provenance says so
("restored from snapshot"). Re-running a restored target (`make fig9`) replaces its folder's records with the new
run's, and from then on the provenance no longer counts that folder as restored (a file of it differs
from the copy, or a file was added)."""
import argparse
import json
import shutil
import sys
from pathlib import Path

from lab.atomic import write_text

from . import paper, provenance, snapshot

FILE = provenance.RESTORED


def fallbacks(profile: str) -> list:
    """The profiles whose outputs the `profile` report shows where its own are absent (paper_values.yaml)."""
    return sorted({fb for e in paper.targets().values() for p, fb in (e.get("fallback") or {}).items()
                   if p == profile})


def restore_one(snap: Path, results: Path) -> list:
    """Copy each target folder of `snap` into `results` where `results` has none; returns the names copied."""
    snap, results = Path(snap), Path(results)
    if not snap.is_dir():
        raise FileNotFoundError(f"{snap}: no committed snapshot to restore from")
    have = set(snapshot.folders(results))
    copied = [name for name in snapshot.folders(snap) if name not in have]
    for name in copied:
        shutil.copytree(snap / name, results / name, dirs_exist_ok=True)
    if copied:
        prov = json.loads((snap / provenance.FILE).read_text()) if (snap / provenance.FILE).exists() else {}
        note = results / FILE
        old = json.loads(note.read_text()) if note.exists() else {}
        here = {"commit": prov.get("snapshot_commit", prov.get("commit", "?")),
                "date": prov.get("snapshot_date", prov.get("date", "?"))}
        earlier = provenance.parse_restored(prov.get("restored from snapshot"))  # the snapshot's own restored folders
        digests = {**old.get("digests", {}), **{name: provenance.folder_digests(results / name) for name in copied}}
        origins = {**old.get("origins", {}), **{name: earlier.get(name, here) for name in copied}}
        write_text(note, json.dumps({"snapshot": str(snap), **here,
                                     "folders": sorted(set(old.get("folders", [])) | set(copied)),
                                     "digests": digests, "origins": origins}, indent=2) + "\n")
    return copied


def restore_bench(snap: Path, results: Path) -> list:
    """The snapshot's benchmark tables (docs/results/bench, report/snapshot.copy_bench) into
    results/bench where results/bench has no file of that name; returns the names copied."""
    snap, results = Path(snap), Path(results)
    names = [f.name for f in sorted(snap.glob("*")) if f.is_file() and not (results / f.name).exists()] \
        if snap.is_dir() else []
    for n in names:
        results.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(snap / n, results / n)
    return names


def restore(profile: str, snapshot_root="docs/results", results_root="results") -> dict:
    """profile -> folders copied, for `profile` and its fallback profiles; "bench" -> the benchmark
    tables copied."""
    out = {"bench": restore_bench(Path(snapshot_root) / "bench", Path(results_root) / "bench")}
    for prof in [profile] + fallbacks(profile):
        snap = Path(snapshot_root) / prof
        if prof != profile and not snap.is_dir():
            continue
        out[prof] = restore_one(snap, Path(results_root) / prof)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--snapshot", default="docs/results", help="the folder holding docs/results/<profile>")
    ap.add_argument("--results", default="results", help="the folder holding results/<profile>")
    a = ap.parse_args(argv)
    try:
        done = restore(a.profile, a.snapshot, a.results)
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    for prof, names in done.items():
        kept = ", ".join(names) if names else "nothing new" if prof == "bench" else \
            "nothing (every target folder already has outputs here)"
        print(f"restore {Path(a.results) / prof}: {kept}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
