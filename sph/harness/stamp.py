"""Make stamps that change only when a run step changed its outputs.

    python -m sph.harness.stamp STAMP DIR -- COMMAND ...

runs COMMAND (a run script, whose own cache decides what to re-run), then writes a digest of the
files under DIR into STAMP, but only when it differs from the one already there. Make re-reads the
stamp's time after the recipe, so the figures that depend on it are re-plotted only when a run
changed; a damaged output that the run script repaired changes the digest and re-plots too. Small
files (metadata, records, relaxed positions) are hashed by content, large ones (trajectories) by size
and modification time; csv tables are left out (they are derived from those files, and downstream
steps such as an evaluation write their own into the same folder).
"""
import hashlib
import subprocess
import sys
from pathlib import Path

SMALL = 8 << 20


def outputs_digest(folder, exclude=()) -> str:
    folder = Path(folder)
    h = hashlib.sha256()
    skip = {Path(e).resolve() for e in exclude}
    for p in sorted(folder.rglob("*")) if folder.exists() else []:
        if not p.is_file() or p.resolve() in skip or p.suffix in (".csv", ".tmp", ".lock", ".log", ".pid", ".png", ".pdf", ".gif"):
            continue
        st = p.stat()
        h.update(str(p.relative_to(folder)).encode())
        if st.st_size <= SMALL:
            h.update(p.read_bytes())
        else:
            h.update(f"{st.st_size}:{st.st_mtime_ns}".encode())
    return h.hexdigest()


def update(stamp, folder) -> bool:
    """Write the digest of `folder` into `stamp` if it changed; True when it did."""
    stamp = Path(stamp)
    new = outputs_digest(folder, exclude=[stamp])
    if stamp.exists() and stamp.read_text().strip() == new:
        return False
    stamp.parent.mkdir(parents=True, exist_ok=True)
    stamp.write_text(new + "\n")
    return True


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if len(argv) < 4 or argv[2] != "--":
        print("usage: python -m sph.harness.stamp STAMP DIR -- COMMAND ...", file=sys.stderr)
        return 2
    stamp, folder, cmd = argv[0], argv[1], argv[3:]
    rc = subprocess.call(cmd)
    if rc != 0:
        return rc
    changed = update(stamp, folder)
    print(f"{stamp}: {'outputs changed' if changed else 'outputs unchanged, nothing to re-plot'}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
