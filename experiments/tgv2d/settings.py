"""Settings of the 2D Taylor-Green experiment: this folder's config.yaml read as a 2D Taylor-Green
study (lab.tgv2d: frozen, validated dataclasses and fingerprints), its name and its paths.
The folder name is the experiment's name: a copy of this folder is an experiment of its own."""
from pathlib import Path
from typing import Optional

from lab import tgv2d
from lab.layout import Study, dx_tag
from lab.study import Method
from lab.tgv2d import Experiment  # noqa: F401  (the settings of this experiment)

HERE = Path(__file__).resolve().parent
NAME = HERE.name
"""The experiment's name is its folder's: results go to results/<profile>/<NAME>."""
CONFIG = HERE / "config.yaml"
STUDY = Study(NAME, HERE)
"""results/<profile>/<NAME>/<method>_dx<dx>/ per run, relaxed_dx<dx>.npy starts and metrics.csv beside
them; the code key of settings.py and the named scripts (lab.layout)."""


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return tgv2d.load(path, profile, overrides)


# -- paths ----------------------------------------------------------------------------------------
out_dir, metrics_path = STUDY.out_dir, STUDY.metrics_path


def run_dir(results, method: str, dx: float) -> Path:
    return STUDY.run_dir(results, method, dx_tag(dx))


def relaxed_path(results, dx: float) -> Path:
    return STUDY.relaxed_path(results, dx_tag(dx))


# -- fingerprints (lab.tgv2d: the settings and the code that can change the numbers) ----------
def relax_fingerprint(exp: Experiment, dx: float) -> str:
    return tgv2d.relax_fingerprint(STUDY, exp, dx)


def run_fingerprint(exp: Experiment, method: Method, dx: float) -> str:
    return tgv2d.run_fingerprint(STUDY, exp, method, dx)
