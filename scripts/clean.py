"""`make clean`: delete a profile's results only when asked twice, and never the expensive ones by accident.

    python3 scripts/clean.py PROFILE [--force] [--expensive]

Lists what results/PROFILE holds (each target folder with its size) and deletes it only with
--force (`make clean FORCE=1`). The profiles whose runs take hours (paper, cpu: paper-scale runs and
trained SitL models) are refused without --expensive (`make clean-expensive PROFILE=paper FORCE=1`).
Standard library only: it runs without the project's virtualenv.
"""
import argparse
import shutil
import sys
from pathlib import Path

EXPENSIVE = ("paper", "cpu")


def size(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file()) if path.is_dir() else path.stat().st_size


def human(n: float) -> str:
    for unit in ("B", "KB", "MB", "GB"):
        if n < 1024 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("profile")
    ap.add_argument("--force", action="store_true")
    ap.add_argument("--expensive", action="store_true")
    ap.add_argument("--root", default="results")
    a = ap.parse_args(argv)
    folder = Path(a.root) / a.profile
    if not folder.exists():
        print(f"clean: {folder} does not exist; nothing to delete")
        return 0
    if a.profile in EXPENSIVE and not a.expensive:
        print(f"clean: refused: {folder} holds {a.profile}-profile runs (hours of CPU, trained models); to delete "
              f"them say so: make clean-expensive PROFILE={a.profile} FORCE=1", file=sys.stderr)
        return 2
    entries = sorted(folder.iterdir())
    total = sum(size(p) for p in entries)
    for p in entries:
        print(f"  {human(size(p)):>9}  {p}")
    if not a.force:
        print(f"clean: would delete {folder} ({human(total)} in {len(entries)} entries); nothing deleted: "
              f"add FORCE=1 to delete it")
        return 0
    shutil.rmtree(folder)
    print(f"clean: deleted {folder} ({human(total)})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
