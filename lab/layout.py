"""Where a study writes, and which of its own files its cache keys cover.

`Study(name, folder)`: results/<profile>/<name>/ holds one folder per run, <method>_<tag>/ (tag: the
resolution, e.g. dx0.02 or n32), relaxed starts relaxed_<tag>.npy and the metrics table metrics.csv;
`code_hash(*scripts)` is the code key of the study's settings.py and the named scripts of `folder`
(with the sph modules they import, lab.keys). Paths and keys only: number-neutral.
"""
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from .configtools import require_name
from .keys import code_fingerprint


def dx_tag(dx: float) -> str:
    """The resolution tag of a spacing: dx0.02."""
    return f"dx{dx:g}"


@dataclass(frozen=True)
class Study:
    """Where a study writes and which of its own files its cache keys cover.

    name    results/<profile>/<name> (an experiment's folder name: a copied folder is a study of its own)
    folder  the folder of the study's own scripts (settings.py, run.py, ...), hashed into its keys
    """

    name: str
    folder: Path

    def out_dir(self, results) -> Path:
        return Path(results) / self.name

    def run_dir(self, results, method: str, tag: str) -> Path:
        """<results>/<name>/<method>_<tag>; a method that is not a name (configtools.NAME, e.g. one
        built in Python with a slash) is a ConfigError: no run writes outside its study's folder."""
        require_name(method, "method name")
        return self.out_dir(results) / f"{method}_{tag}"

    def relaxed_path(self, results, tag: str) -> Path:
        return self.out_dir(results) / f"relaxed_{tag}.npy"

    def metrics_path(self, results) -> Path:
        return self.out_dir(results) / "metrics.csv"

    def code_hash(self, *scripts: str, modules: Iterable[str] = ()) -> str:
        """Hash of the solver's code, settings.py and the named scripts of the study's folder, with
        the sph modules they import (lab.keys.code_fingerprint) and `modules`."""
        return code_fingerprint([Path(self.folder) / n for n in ("settings.py", *scripts)], tuple(modules))
