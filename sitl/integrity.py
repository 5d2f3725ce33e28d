"""SitL's files verified before they are trusted (issue 23, class 3).

The dataset (sitl/generate.py) and each training's checkpoint (sitl/train.py) record the digest of
every file they wrote (`lab.stamp.file_digest`: content for small files, size and
modification time for large ones). Before such a file is read again, `damaged` compares it with the
record and `unreadable` opens it the way its reader will; a file that fails either is set aside
(``<name>.stale-<n>``, `lab.runs.set_aside`) with one line naming it, and what it belonged
to is made again. Nothing is deleted: the newest set-aside copies stay beside the original.
"""
import json
import pickle
from pathlib import Path
from typing import Optional

import numpy as np

from lab.runs import set_aside
from lab.stamp import file_digest

CHECKPOINT_FILES = ("params_tree.pkl", "params_array.npy", "state_tree.pkl", "state_array.npy",
                    "opt_state.pkl", "metadata_ckp.json")
"""What LagrangeBench's `save_haiku` writes into a checkpoint folder (and its best/ copy)."""


def digests(base: Path, names) -> dict:
    """{name relative to `base`: digest} of the files `names` below `base`."""
    return {str(n): file_digest(Path(base) / n) for n in names}


def all_damaged(base: Path, recorded: Optional[dict]) -> list:
    """[(path, why)] of every file below `base` that differs from its recorded digest, in name order
    (empty also when nothing was recorded: files made before digests were kept)."""
    out = []
    for name, d in sorted((recorded or {}).items()):
        now = file_digest(Path(base) / name)
        if now != d:
            out.append((Path(base) / name, "missing" if now == "absent" else "changed since it was written (truncated?)"))
    return out


def damaged(base: Path, recorded: Optional[dict]) -> Optional[tuple]:
    """(path, why) of the first file below `base` that differs from its recorded digest, else None."""
    bad = all_damaged(base, recorded)
    return bad[0] if bad else None


def _read_npy_all(p: Path, n: int) -> None:
    with p.open("rb") as f:
        for _ in range(n):
            np.load(f)


def unreadable_checkpoint(folder: Path) -> Optional[tuple]:
    """(path, why) of the first file of a LagrangeBench checkpoint folder that is missing or cannot be
    read as `lagrangebench.utils.load_haiku` reads it, else None."""
    folder = Path(folder)
    for name in CHECKPOINT_FILES:
        p = folder / name
        if not p.is_file():
            return p, "missing"
    try:
        for kind in ("params", "state"):
            p = folder / f"{kind}_tree.pkl"
            with p.open("rb") as f:
                tree = pickle.load(f)
            p = folder / f"{kind}_array.npy"
            _read_npy_all(p, _n_leaves(tree))
        p = folder / "opt_state.pkl"
        with p.open("rb") as f:
            pickle.load(f)
        p = folder / "metadata_ckp.json"
        int(json.loads(p.read_text())["step"])
    except Exception as e:  # noqa: BLE001 - any failure to read is damage, named with its file
        return p, f"unreadable ({type(e).__name__}: {' '.join(str(e).split())[:120]})"
    return None


def _n_leaves(tree) -> int:
    import jax
    return len(jax.tree_util.tree_leaves(tree))


def set_aside_damaged(path: Path, why: str, then: str, whole: Optional[Path] = None) -> None:
    """One line naming the damaged file; `whole` (default: the file) is set aside. A file that is not
    there at all (deleted by hand) has nothing to set aside: one line says so."""
    target = Path(whole) if whole is not None else Path(path)
    if not target.exists():
        print(f"{path}: missing; {then}", flush=True)
        return
    set_aside(target, f"{path} is damaged ({why})" if whole is not None else f"damaged ({why})", then=then)
