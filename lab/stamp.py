"""Make stamps of a run step: a manifest of exactly the outputs the current config made.

    python -m lab.stamp STAMP DIR -- COMMAND ...

runs COMMAND (a run script, whose own cache decides what to re-run), then writes into STAMP the
manifest of the step's current outputs, only when it differs from the one already there:

    {"digest": "<sha256 of the outputs>", "outputs": {"tgv2d/sph_dx0.1": "<sha256>", "tgv2d/metrics.csv": ...}}

(paths relative to STAMP's folder). Which outputs are current is what the step declares while it runs
(`note_current`: `lab.runs.run_cached` notes each run folder of the config (relaxed starts
are inputs of those runs, inside their keys), `tables.write_table` the metrics table, `record.save_record` the run's folder), so
a method or dx removed from the profile drops out of the manifest although its folder stays on disk,
and a rewritten metrics table changes it. A step that declares nothing (a script not built on
lab.runs) stands for everything under DIR. The deliverables made from a step
(`lab.deliver`) hash the stamp, so they are re-made exactly when the current runs changed;
`current_folders` gives the run folders a stamp lists (the atlas gathers only those).

Small files are hashed by content, large ones (trajectories) by size and modification time; lock,
log, temporary, figure and set-aside (``*.stale-<n>``) files and other stamps are left out.
"""
import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Optional

from .atomic import write_text

SMALL = 8 << 20
ENV = "SPH_STAMP_OUTPUTS"
"""The file a stamped step's processes append their current outputs to (set by `main`)."""
SKIP_SUFFIXES = (".tmp", ".lock", ".log", ".pid", ".png", ".pdf", ".gif", ".done")


def _skipped(p: Path) -> bool:
    return p.suffix in SKIP_SUFFIXES or ".stale-" in p.name or p.name.startswith(".")


def file_digest(p) -> str:
    """sha256 of a file's content (size and mtime for files over 8 MB); "absent" for no file."""
    p = Path(p)
    if not p.is_file():
        return "absent"
    st = p.stat()
    if st.st_size > SMALL:
        return f"size:{st.st_size}:mtime:{st.st_mtime_ns}"
    return hashlib.sha256(p.read_bytes()).hexdigest()


def path_digest(path) -> str:
    """Digest of a file, or of a folder's files (names and digests, the skipped kinds left out)."""
    path = Path(path)
    if not path.is_dir():
        return file_digest(path)
    h = hashlib.sha256()
    for p in sorted(path.rglob("*")):
        if p.is_file() and not any(_skipped(Path(part)) for part in p.relative_to(path).parts):
            h.update(f"{p.relative_to(path)}\0{file_digest(p)}\n".encode())
    return h.hexdigest()


def note_current(*paths) -> None:
    """Declare `paths` (files or run folders) outputs of exactly the current config for the stamp of
    the make step this process runs under (no-op outside `python -m lab.stamp`)."""
    target = os.environ.get(ENV)
    if not target:
        return
    with open(target, "a") as f:
        for p in paths:
            f.write(str(Path(p).resolve()) + "\n")


def manifest(stamp, folder, noted=()) -> dict:
    """The manifest of the current outputs: `noted` paths (declared by the step), else every entry
    of `folder` (the stamp itself and the skipped kinds left out), keyed relative to the stamp's folder."""
    base = Path(stamp).resolve().parent
    paths = sorted({Path(p).resolve() for p in noted})
    if not paths:
        folder = Path(folder)
        paths = sorted(p.resolve() for p in folder.iterdir() if not _skipped(p)) if folder.exists() else []
    outputs = {os.path.relpath(p, base): path_digest(p) for p in paths if p != Path(stamp).resolve()}
    digest = hashlib.sha256(json.dumps(outputs, sort_keys=True).encode()).hexdigest()
    return {"digest": digest, "outputs": outputs}


def read(stamp) -> Optional[dict]:
    """A stamp's manifest, or None (no stamp, or one written before stamps were manifests)."""
    try:
        m = json.loads(Path(stamp).read_text())
    except (OSError, ValueError):
        return None
    return m if isinstance(m, dict) and isinstance(m.get("outputs"), dict) else None


def current_folders(root) -> Optional[set]:
    """The resolved paths every stamp (*.done) below `root` lists as current, or None when `root` has
    no stamp manifest (then every folder there counts)."""
    found = None
    for s in sorted(Path(root).rglob("*.done")) if Path(root).exists() else []:
        m = read(s)
        if m is not None:
            found = (found or set()) | {(s.parent / p).resolve() for p in m["outputs"]}
    return found


def update(stamp, folder, noted=()) -> bool:
    """Write the manifest of `folder`'s current outputs into `stamp` if it changed; True when it did."""
    stamp = Path(stamp)
    new = manifest(stamp, folder, noted)
    old = read(stamp)
    if old is not None and old.get("digest") == new["digest"]:
        return False
    write_text(stamp, json.dumps(new, indent=1, sort_keys=True) + "\n")
    return True


def run_command(cmd, env: dict) -> int:
    """Run `cmd` with `env` added; its exit code. Ctrl-C reaches the command too (the terminal's process
    group): wait for it to stop and return its code (130) without a traceback here."""
    proc = subprocess.Popen(cmd, env={**os.environ, **env})
    while True:
        try:
            rc = proc.wait()
            return 128 - rc if rc < 0 else rc  # killed by signal n: 128 + n, as a shell reports it
        except KeyboardInterrupt:
            continue


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) < 4 or argv[2] != "--":
        print("usage: python -m lab.stamp STAMP DIR -- COMMAND ...", file=sys.stderr)
        return 2
    stamp, folder, cmd = argv[0], argv[1], argv[3:]
    with tempfile.NamedTemporaryFile("r", prefix="sph-outputs-", suffix=".txt") as noted:
        rc = run_command(cmd, {ENV: noted.name})
        if rc != 0:
            return rc
        paths = [line.strip() for line in noted.read().splitlines() if line.strip()]
    changed = update(stamp, folder, paths)
    n = len(read(stamp)["outputs"])
    print(f"{stamp}: {'current outputs changed' if changed else 'current outputs unchanged'} ({n} listed)",
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
