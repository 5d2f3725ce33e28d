"""The accuracy-cost atlas (experiments/accuracy/README.md) as a study of the protocol (lab.experiment).

Its runs are a TGV sweep: every method x dx x dtype x kernel of the profile, each a run of
experiments/tgv2d (its study.py, its config's `tgv.base_profile` with the sweep's overrides). The
harness runs them as one tgv2d experiment per (kernel, dtype) (`parts`), each with its own cached,
resumable runs, records and table, into results/<profile>/accuracy/tgv/<kernel>_<dtype>/tgv2d/.
plot_accuracy.py, the atlas, then reads the run records of exactly the current runs of the sweep and
of the experiments in `gather` (written by their own runs: Figs. 6-8, heat validation, sitl/cost.py),
never re-running anything.
"""
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from lab.configtools import ConfigError, load_profile, require, to_mapping
from lab.experiment import Experiment, load_study
from sph.kernels import KERNELS
from sph.precision import DTYPES

HERE = Path(__file__).resolve().parent
NAME = HERE.name
TGV_FOLDER = HERE.parent / "tgv2d"
"""The experiment the TGV sweep runs (its study.py, and its config.yaml's profiles: tgv.base_profile)."""
TGV = load_study(TGV_FOLDER)


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
class Settings:
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


def kernel_tag(kernel: str) -> str:
    """<name>, or <name>_h<factor> for a sweep kernel entry with its own smoothing length."""
    name, h_factor = kernel_spec(kernel)
    return name if h_factor is None else f"{name}_h{h_factor:g}"


def out_dir(results) -> Path:
    return Path(results) / NAME


def tgv_results(results, kernel: str, dtype: str) -> Path:
    """The results root of one (kernel entry, dtype) tgv2d experiment of the sweep: <name>_<dtype>,
    or <name>_h<factor>_<dtype> for an entry with its own smoothing length."""
    return out_dir(results) / "tgv" / f"{kernel_tag(kernel)}_{dtype}"


def tgv_overrides(sw: TgvSweep, kernel: str, dtype: str) -> dict:
    """The overrides of tgv2d's base profile for one (kernel entry, dtype) of the sweep, validated as
    tgv2d's own config (a kernel entry "name@<factor>" also sets numerics.h_factor)."""
    base = load_profile(TGV.Settings, TGV_FOLDER / "config.yaml", sw.base_profile)
    names = [m.name for m in base.methods]
    for i, m in enumerate(sw.methods):
        if m not in names:
            raise ConfigError(f"tgv.methods[{i}]: {m!r} is not a method of tgv2d's {sw.base_profile!r} "
                              f"profile ({names})")
    methods = [{"name": m.name, "effects": to_mapping(m.effects)} for m in base.methods if m.name in sw.methods]
    name, h_factor = kernel_spec(kernel)
    numerics = {"kernel": name, "dtype": dtype}
    if h_factor is not None:
        numerics["h_factor"] = h_factor
    return {"numerics": numerics, "methods": methods, "dx": list(sw.dx),
            "t_end": sw.t_end, "frames": sw.frames, "eval_times": [sw.t_end / 2, sw.t_end]}


def tgv_experiment(s: Settings, kernel: str, dtype: str, results=".") -> Experiment:
    """The 2D Taylor-Green experiment of one (kernel entry, dtype) of the sweep, its results under
    tgv_results(results, ...)."""
    sw = s.tgv
    return Experiment(TGV_FOLDER, sw.base_profile, tgv_results(results, kernel, dtype),
                      overrides=tgv_overrides(sw, kernel, dtype))


def parts(exp):
    """The sweep's tgv2d experiments, one per (kernel, dtype), under the harness's results root
    (lab.experiment runs them, one after the other, in place of this folder's own runs)."""
    s = exp.settings
    for kernel in s.tgv.kernels:
        for dtype in s.tgv.dtypes:
            print(f"accuracy: TGV sweep, kernel {kernel}, {dtype}", flush=True)
            yield tgv_experiment(s, kernel, dtype, exp.results)


# -- the runs: tgv2d's, one set per (kernel, dtype) ----------------------------------------------
@dataclass(frozen=True)
class SweepRun:
    """A run of the sweep: tgv2d's run `tgv` of one (kernel entry, dtype); `name` says all three."""

    name: str
    kernel: str
    dtype: str
    tgv: object

    @property
    def t_end(self) -> float:
        return self.tgv.t_end

    @property
    def frames(self) -> int:
        return self.tgv.frames

    @property
    def method(self) -> str:
        return self.tgv.method


def runs(s: Settings) -> list:
    """Every run of the sweep, (kernel, dtype) by (kernel, dtype) as `parts` runs them."""
    out = []
    for kernel in s.tgv.kernels:
        for dtype in s.tgv.dtypes:
            tgv = load_profile(TGV.Settings, TGV_FOLDER / "config.yaml", s.tgv.base_profile,
                               tgv_overrides(s.tgv, kernel, dtype))
            out += [SweepRun(f"{kernel_tag(kernel)}_{dtype}-{r.name}", kernel, dtype, r) for r in TGV.runs(tgv)]
    return out


def start(run: SweepRun):
    return TGV.start(run.tgv)


def scene(run: SweepRun, r: np.ndarray):
    """What tgv2d builds for the run."""
    return TGV.scene(run.tgv, r)


def run_options(run: SweepRun) -> dict:
    return TGV.run_options(run.tgv)


def metrics(run: SweepRun, traj: dict) -> dict:
    """What tgv2d measures of the run (its record is tgv2d's: the atlas's TGV problem)."""
    return TGV.metrics(run.tgv, traj)
