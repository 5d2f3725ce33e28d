"""A study: named methods (the effects their scenes declare) run at each resolution of a profile.

What the Taylor-Green studies share (experiments/tgv2d, experiments/tgv3d and the accuracy atlas's
TGV sweep): the method list and its checks, the cached run's spec and the sweep over (resolution,
method); the relaxed start of a periodic box is the case's (sph.cases.relaxed). Where a
study writes and which of its files its keys cover is `lab.layout.Study`. What a study
measures stays with the study.
"""
import time
from dataclasses import dataclass, field
from typing import Callable, Optional

import pandas as pd

from sph.config import Effects
from sph.errors import require
from . import runs
from .layout import Study

KEEPABLE = ("velocity", "momentum_velocity", "density", "pressure")
"""Per-frame fields a study may keep besides position (lab.io.FIELDS)."""


@dataclass(frozen=True)
class Method:
    """A named solver variant: the effects its scene declares."""

    name: str
    effects: Effects = field(default_factory=Effects)


def check_methods(methods) -> list:
    """The method names, each checked to be unique (at least one method)."""
    require(len(methods) > 0, "methods", "needs at least one method")
    names = [m.name for m in methods]
    for i, n in enumerate(names):
        require(names.index(n) == i, f"methods[{i}].name", f"{n!r} appears twice")
    return names


def check_output(exp) -> None:
    """The output settings every study has: `connectivity_radius_factor` and the kept fields."""
    require(exp.connectivity_radius_factor > 0, "connectivity_radius_factor",
            f"must be positive, got {exp.connectivity_radius_factor}")
    for i, k in enumerate(exp.keep):
        require(k in KEEPABLE, f"keep[{i}]", f"{k!r} is not one of {list(KEEPABLE)}")


def run_spec(study: Study, exp, method: Method, tag: str, results, fingerprint: str, metadata: dict) -> runs.RunSpec:
    """The cached run of `method` at the resolution `tag` of experiment `exp` (its case, t_end, frames,
    keep, connectivity_radius_factor; the blow-up limit c_ref_factor * u_ref)."""
    return runs.RunSpec(folder=study.run_dir(results, method.name, tag), case=exp.case, method=method.name,
                        fingerprint=fingerprint, t_end=exp.t_end, frames=exp.frames, keep=exp.keep,
                        connectivity_radius_factor=exp.connectivity_radius_factor, metadata=metadata,
                        u_limit=exp.numerics.c_ref_factor * exp.material.u_ref)


def sweep(study: Study, results, resolutions, methods, run_one: Callable,
          only: Optional[list] = None) -> pd.DataFrame:
    """`run_one(method, resolution)` -> metrics row for every resolution and method (or the methods
    named in `only`); one summary line; the rows as a table."""
    t0 = time.perf_counter()
    rows = [run_one(m, res) for res in resolutions for m in methods if only is None or m.name in only]
    print(f"{study.name}: {len(rows)} runs in {time.perf_counter() - t0:.1f} s -> {study.metrics_path(results)}",
          flush=True)
    return pd.DataFrame(rows)
