"""The 2D Taylor-Green study's settings: one profile of a config.yaml as a frozen, validated
dataclass, its resolution tags and the fingerprints that decide whether a cached result still
matches its inputs. Read by experiments/tgv2d (and any copy of it) and by the accuracy atlas's TGV
sweep; the runs and their metrics are `lab.tgv2d_runs`.
"""
from dataclasses import dataclass, field
from typing import Optional

from sph.config import Material, Numerics
from sph.relax import Relaxation
from .configtools import load_profile, require, require_finite, to_mapping
from .keys import digest
from .layout import Study
from .study import Method, check_methods, check_output

RELAX_MODULES = ("sph.cases.tgv",)
"""The code of a relaxed start besides the solver's (the TGV scene and its relaxation, sph.cases.relaxed)."""


@dataclass(frozen=True)
class Experiment:
    """One profile of a 2D Taylor-Green study (see experiments/tgv2d/config.yaml for each key)."""

    methods: tuple[Method, ...]
    dx: tuple[float, ...]
    t_end: float
    case: str = "tgv2d"
    material: Material = field(default_factory=Material)
    numerics: Numerics = field(default_factory=Numerics)
    frames: int = 200
    eval_times: tuple[float, ...] = (0.5, 1.0, 2.0)
    keep: tuple[str, ...] = ("velocity", "density", "pressure")
    connectivity_radius_factor: float = 1.45
    relaxation: Relaxation = field(default_factory=Relaxation)
    fig4_method: str = "tvf"

    def __post_init__(self):
        require_finite(self)
        names = check_methods(self.methods)
        require(len(self.dx) > 0, "dx", "needs at least one particle spacing")
        for i, dx in enumerate(self.dx):
            require(dx > 0 and abs(1.0 / dx - round(1.0 / dx)) < 1e-6, f"dx[{i}]",
                    f"must divide the unit square into whole cells (1/dx integer), got {dx}")
            require(self.dx.index(dx) == i, f"dx[{i}]", f"{dx} appears twice (each run would be listed twice)")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.material.eta > 0, "material.eta",
                "must be positive: the Taylor-Green reference decay exp(-8 pi^2 t / Re) and Re = rho_ref u_ref / eta "
                f"need a viscosity, got {self.material.eta}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        for i, t in enumerate(self.eval_times):
            require(t >= 0, f"eval_times[{i}]", f"must be >= 0, got {t}")
        check_output(self)
        require(self.fig4_method in names, "fig4_method", f"{self.fig4_method!r} is not one of the methods {names}")

    @property
    def re(self) -> float:
        """Reynolds number rho U L / eta with L = 1 (the unit square)."""
        return self.material.rho_ref * self.material.u_ref / self.material.eta

    def method(self, name: str) -> Method:
        return next(m for m in self.methods if m.name == name)


def load(path, profile: str, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return load_profile(Experiment, path, profile, overrides)


def relax_fingerprint(study: Study, exp: Experiment, dx: float) -> str:
    """The relaxed start at `dx`: its settings and the code that relaxes (the solver's, the study's
    relaxation and scene of sph.cases.tgv, settings.py of the study's folder), without docstrings or comments."""
    return digest({"dx": dx, "material": to_mapping(exp.material), "numerics": to_mapping(exp.numerics),
                   "relaxation": to_mapping(exp.relaxation), "code": study.code_hash(modules=RELAX_MODULES)})


def run_fingerprint(study: Study, exp: Experiment, method: Method, dx: float) -> str:
    """The run of `method` at `dx`: its settings, its relaxed start and the code of the solver and of
    the study's settings.py and run.py (with the sph modules they import: the study's runs)."""
    return digest({"case": exp.case, "dx": dx, "method": to_mapping(method), "material": to_mapping(exp.material),
                   "numerics": to_mapping(exp.numerics), "t_end": exp.t_end, "frames": exp.frames,
                   "keep": list(exp.keep), "relax": relax_fingerprint(study, exp, dx),
                   "code": study.code_hash("run.py")})
