"""Where a report's numbers were made: commit, date, CPU / GPU model, jax / jaxlib / jax-md /
lagrangebench versions, profile. `collect()` reads them from this checkout and machine;
`load_or_collect(results)` prefers a provenance.json stored with the results (a snapshot carries
the provenance of the machine that made its runs, not of the one that copies them)."""
import datetime
import hashlib
import json
import platform
import subprocess
from importlib import metadata
from pathlib import Path

from .paper import ROOT

PACKAGES = ("jax", "jaxlib", "jax-md")
RESTORED = "restored.json"  # written by `make restore` (report/restore.py)
FILE = "provenance.json"


def _git(*args) -> str:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=20).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


DIRTY = " (with uncommitted changes)"


def dirty_paths() -> list:
    """The tracked files whose working copy differs from HEAD (`git status --porcelain`, untracked
    files left out): what a record made now would carry that the commit does not."""
    out = _git("status", "--porcelain", "--untracked-files=no")
    return [line.split(None, 1)[1] for line in out.splitlines() if len(line.split(None, 1)) == 2]


def commit() -> str:
    sha = _git("rev-parse", "HEAD") or "unknown"
    return sha + (DIRTY if dirty_paths() else "")


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def cpu_count() -> int:
    import os
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 0)


def gpu_model() -> str:
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                             text=True, timeout=20)
        names = [n.strip() for n in out.stdout.splitlines() if n.strip()]
        return ", ".join(names) if out.returncode == 0 and names else "none"
    except (OSError, subprocess.SubprocessError):
        return "none"


def version(pkg: str) -> str:
    try:
        return metadata.version(pkg)
    except metadata.PackageNotFoundError:
        return "not installed"


def lagrangebench_version(venv=ROOT / ".venv-lb") -> str:
    """LagrangeBench's version in .venv-lb (read from its dist-info; that environment is not this one)."""
    found = sorted(Path(venv).glob("lib/python*/site-packages/lagrangebench-*.dist-info"))
    return found[-1].name[len("lagrangebench-"):-len(".dist-info")] if found else "not installed (.venv-lb)"


def collect(profile: str) -> dict:
    return {"profile": profile, "commit": commit(),
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
            "cpu": f"{cpu_model()} ({cpu_count()} cores available)", "gpu": gpu_model(),
            **{p: version(p) for p in PACKAGES}, "lagrangebench": lagrangebench_version(),
            "python": platform.python_version()}


def load_or_collect(results, profile: str) -> dict:
    """The results' own provenance.json (a snapshot's) if there is one, else this machine's, with the
    folders `make restore` took from a committed snapshot (report/restore.py) named."""
    p = Path(results) / FILE
    if p.exists():
        return json.loads(p.read_text())
    out = collect(profile)
    note = restored(results)
    if note:
        out["restored from snapshot"] = note
    return out


def folder_digests(folder) -> dict:
    """sha256 of every file below `folder` (relative path -> hex digest)."""
    folder = Path(folder)
    return {str(f.relative_to(folder)): hashlib.sha256(f.read_bytes()).hexdigest()
            for f in sorted(folder.rglob("*")) if f.is_file()}


def restored(results) -> str:
    """Which folders of `results` came from which snapshot (`make restore`) and are still as restored,
    or ''. A folder some target wrote into since, every restored file of it changed, is not named; one
    that keeps some restored files beside new ones (a shared folder such as ldc2d, whose Fig. 6 runs were
    made again here and whose Fig. 7 runs were not) is named "in part", with how many of its files are
    as restored; a restore record without digests (older) names every folder it copied. Each folder is
    named with the snapshot its files were first made for (a snapshot restored from an earlier one
    passes the earlier one on, its "in part" too), grouped: "a, b [in part: ...]: from the snapshot of
    C (D); c: from ..."."""
    p = Path(results) / RESTORED
    if not p.exists():
        return ""
    r = json.loads(p.read_text())
    digests = r.get("digests")
    origins = r.get("origins", {})
    groups = {}
    for f in r["folders"]:
        o = origins.get(f, {"commit": r["commit"], "date": r["date"]})
        tag = o.get("part", "")
        if digests is not None:
            cur, then = folder_digests(Path(results) / f), digests.get(f) or {}
            kept = sum(cur.get(k) == v for k, v in then.items())
            if not kept:
                continue
            if cur != then:
                tag = f"[in part: {kept} of its {len(cur)} files as restored]"
        groups.setdefault((o["commit"], o["date"]), []).append(f + (f" {tag}" if tag else ""))
    return "; ".join(f"{', '.join(fs)}: from the snapshot of {c} ({d})" for (c, d), fs in groups.items())


def parse_restored(note: str) -> dict:
    """folder -> {"commit", "date"[, "part"]} from a provenance's "restored from snapshot" line
    (`restored`); "part" is the "[in part: ...]" of a folder restored in part."""
    out = {}
    for group in filter(None, (g.strip() for g in (note or "").split("; "))):
        folders, _, origin = group.partition(": from the snapshot of ")
        commit, _, date = origin.rpartition(" (")
        for f in (x.strip() for x in folders.split(",")):
            name, _, part = f.partition(" [")
            if name:
                out[name] = {"commit": commit, "date": date.rstrip(")"), **({"part": "[" + part} if part else {})}
    return out


def display(prov: dict) -> dict:
    """The provenance as the report's table shows it: a list (a dirty snapshot's changed paths and
    files) condensed to its length and where to read it in full."""
    return {k: (f"{len(v)} (listed in {FILE})" if isinstance(v, list) else v) for k, v in prov.items()}
