"""Settings of the 2D Taylor-Green experiment: config.yaml -> frozen, validated dataclasses, paths,
and the fingerprints that decide whether a cached result still matches its inputs."""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import sph
from sph.harness.configtools import load_profile, require, require_finite, to_mapping
from sph.harness.keys import code_fingerprint, digest
from sph.relax import Relaxation  # noqa: F401  (the relaxation settings of this experiment)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
NAME = HERE.name
"""The experiment's name is its folder's: results go to results/<profile>/<NAME>."""
CONFIG = HERE / "config.yaml"
KEEPABLE = ("velocity", "momentum_velocity", "density", "pressure")


@dataclass(frozen=True)
class Method:
    """A named solver variant: the effects its scene declares."""

    name: str
    effects: sph.Effects = field(default_factory=sph.Effects)


@dataclass(frozen=True)
class Experiment:
    """One profile of the experiment (see config.yaml for the meaning of each key)."""

    methods: tuple[Method, ...]
    dx: tuple[float, ...]
    t_end: float
    case: str = "tgv2d"
    material: sph.Material = field(default_factory=sph.Material)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    frames: int = 200
    eval_times: tuple[float, ...] = (0.5, 1.0, 2.0)
    keep: tuple[str, ...] = ("velocity", "density", "pressure")
    connectivity_radius_factor: float = 1.45
    relaxation: Relaxation = field(default_factory=Relaxation)
    fig4_method: str = "tvf"

    def __post_init__(self):
        require_finite(self)
        require(len(self.methods) > 0, "methods", "needs at least one method")
        names = [m.name for m in self.methods]
        for i, n in enumerate(names):
            require(names.index(n) == i, f"methods[{i}].name", f"{n!r} appears twice")
        require(len(self.dx) > 0, "dx", "needs at least one particle spacing")
        for i, dx in enumerate(self.dx):
            require(dx > 0 and abs(1.0 / dx - round(1.0 / dx)) < 1e-6, f"dx[{i}]",
                    f"must divide the unit square into whole cells (1/dx integer), got {dx}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.material.eta > 0, "material.eta",
                "must be positive: the Taylor-Green reference decay exp(-8 pi^2 t / Re) and Re = rho_ref u_ref / eta "
                f"need a viscosity, got {self.material.eta}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        for i, t in enumerate(self.eval_times):
            require(t >= 0, f"eval_times[{i}]", f"must be >= 0, got {t}")
        require(self.connectivity_radius_factor > 0, "connectivity_radius_factor",
                f"must be positive, got {self.connectivity_radius_factor}")
        for i, k in enumerate(self.keep):
            require(k in KEEPABLE, f"keep[{i}]", f"{k!r} is not one of {list(KEEPABLE)}")
        require(self.fig4_method in names, "fig4_method", f"{self.fig4_method!r} is not one of the methods {names}")

    @property
    def re(self) -> float:
        """Reynolds number rho U L / eta with L = 1 (the unit square)."""
        return self.material.rho_ref * self.material.u_ref / self.material.eta

    def method(self, name: str) -> Method:
        return next(m for m in self.methods if m.name == name)


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return load_profile(Experiment, path, profile, overrides)


# -- paths ----------------------------------------------------------------------------------------
def dx_tag(dx: float) -> str:
    return f"dx{dx:g}"


def out_dir(results) -> Path:
    """results/<profile>/<NAME> (tgv2d for this folder)."""
    return Path(results) / NAME


def run_dir(results, method: str, dx: float) -> Path:
    return out_dir(results) / f"{method}_{dx_tag(dx)}"


def relaxed_path(results, dx: float) -> Path:
    return out_dir(results) / f"relaxed_{dx_tag(dx)}.npy"


def metrics_path(results) -> Path:
    return out_dir(results) / "metrics.csv"


# -- fingerprints ---------------------------------------------------------------------------------
def code_hash(*scripts: str) -> str:
    """Hash of the solver sources (sph/**/*.py), settings.py and the named scripts of this folder."""
    return code_fingerprint([HERE / n for n in ("settings.py", *scripts)])  # + sph.relax via relax.py


def relax_fingerprint(exp: Experiment, dx: float) -> str:
    return digest({"dx": dx, "material": to_mapping(exp.material), "numerics": to_mapping(exp.numerics),
                    "relaxation": to_mapping(exp.relaxation), "code": code_hash("relax.py")})


def run_fingerprint(exp: Experiment, method: Method, dx: float) -> str:
    return digest({"case": exp.case, "dx": dx, "method": to_mapping(method), "material": to_mapping(exp.material),
                    "numerics": to_mapping(exp.numerics), "t_end": exp.t_end, "frames": exp.frames,
                    "keep": list(exp.keep), "relax": relax_fingerprint(exp, dx), "code": code_hash("run.py")})
