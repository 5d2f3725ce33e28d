"""Settings of the accuracy-cost atlas: config.yaml -> frozen, validated dataclasses, and paths."""
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from lab.configtools import load_profile, require
from sph.kernels import KERNELS
from sph.precision import DTYPES

HERE = Path(__file__).resolve().parent
NAME = HERE.name
CONFIG = HERE / "config.yaml"
TGV_FOLDER = HERE.parent / "tgv2d"
"""The experiment the TGV sweep runs (its study.py, and its config.yaml's profiles: tgv.base_profile)."""


@dataclass(frozen=True)
class TgvSweep:
    """The TGV sweep: every method x dx x dtype x kernel, each a run of experiments/tgv2d.

    base_profile  profile of experiments/tgv2d/config.yaml supplying material, numerics, relaxation
    kernels       kernel names (sph.kernels.KERNELS), each optionally with its own smoothing length
                  h = <factor> dx as "name@<factor>" (e.g. "wendland_c2@1.5"); without it the base
                  profile's numerics.h_factor
    error         the err_<name> column of the TGV records that the atlas plots
    """

    methods: tuple[str, ...]
    dx: tuple[float, ...]
    dtypes: tuple[str, ...] = ("float64",)
    kernels: tuple[str, ...] = ("quintic",)
    t_end: float = 2.0
    frames: int = 50
    base_profile: str = "paper"
    error: str = "u_max_mean"

    def __post_init__(self):
        require(len(self.methods) > 0, "tgv.methods", "needs at least one method")
        require(len(self.dx) > 0, "tgv.dx", "needs at least one spacing")
        for i, d in enumerate(self.dtypes):
            require(d in DTYPES, f"tgv.dtypes[{i}]", f"{d!r} is not one of {sorted(DTYPES)}")
        for i, k in enumerate(self.kernels):
            kernel_spec(k, f"tgv.kernels[{i}]")
        require(bool(np.isfinite(self.t_end)) and self.t_end > 0, "tgv.t_end", f"must be finite and positive, got {self.t_end}")
        require(self.frames >= 1, "tgv.frames", f"must be >= 1, got {self.frames}")


@dataclass(frozen=True)
class Atlas:
    """One profile of the atlas (see config.yaml)."""

    tgv: TgvSweep
    gather: tuple[str, ...] = ()
    levels: tuple[float, ...] = (0.1, 0.03, 0.01, 0.003)

    def __post_init__(self):
        for i, lv in enumerate(self.levels):
            require(bool(np.isfinite(lv)) and lv > 0, f"levels[{i}]", f"must be a positive error level, got {lv}")
        for i, g in enumerate(self.gather):
            require((HERE.parent / g).is_dir() or (HERE.parents[1] / g / "rules.mk").is_file(), f"gather[{i}]",
                    f"{g!r} is not a folder of experiments/ nor a top-level experiment (sitl/)")


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Atlas:
    return load_profile(Atlas, path, profile, overrides)


def out_dir(results) -> Path:
    return Path(results) / NAME


def kernel_spec(spec: str, where: str = "tgv.kernels") -> tuple[str, Optional[float]]:
    """("name", h_factor or None) of a sweep kernel entry "name" or "name@<h_factor>"."""
    name, _, h = str(spec).partition("@")
    require(name in KERNELS, where, f"{name!r} is not one of {sorted(KERNELS)}")
    if not _:
        return name, None
    try:
        h_factor = float(h)
    except ValueError:
        h_factor = float("nan")
    require(bool(np.isfinite(h_factor)) and h_factor > 0, where,
            f"{spec!r}: the smoothing length after '@' must be a positive number (h = factor x dx)")
    return name, h_factor


def tgv_results(results, kernel: str, dtype: str) -> Path:
    """The results root of one (kernel entry, dtype) tgv2d experiment of the sweep: <name>_<dtype>,
    or <name>_h<factor>_<dtype> for an entry with its own smoothing length."""
    name, h_factor = kernel_spec(kernel)
    tag = name if h_factor is None else f"{name}_h{h_factor:g}"
    return out_dir(results) / "tgv" / f"{tag}_{dtype}"
