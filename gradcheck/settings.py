"""Settings of the gradient check (JAX-SPH Fig. 1): config.yaml -> frozen, validated dataclasses,
result paths and the fingerprints that decide whether a cached result still matches its inputs."""
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Optional

import sph
from lab.configtools import load_profile, require, require_finite, to_mapping
from lab.keys import digest
from lab.layout import Study

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CONFIG = HERE / "config.yaml"
KINDS = ("tgv", "ldc")
DTYPES = ("float64", "float32")


@dataclass(frozen=True)
class Case:
    """A scene whose gradient is checked: `kind` tgv (periodic Taylor-Green vortex, sph.cases.tgv) or
    ldc (lid-driven cavity, sph.cases.ldc; needs effects.walls) with the effects its scene declares."""

    name: str
    kind: str
    effects: sph.Effects = field(default_factory=sph.Effects)

    def __post_init__(self):
        require(self.kind in KINDS, "kind", f"{self.kind!r} is not one of {list(KINDS)}")
        if self.kind == "ldc":
            require(self.effects.walls is not None, "effects.walls", "the cavity needs walls (no_slip or free_slip)")
        else:
            require(self.effects.walls is None and self.effects.gravity is None, "effects",
                    "the Taylor-Green vortex is a periodic box without walls or gravity")


@dataclass(frozen=True)
class Growth:
    """Gradient norm against rollout length: d E_kin(n steps) / d r0 for every n of `steps`.

    steps      rollout lengths n
    dtype      precision of these runs
    fd_check   also compare grad . d with a central difference along one random unit direction d
               (eps of the main check) for every n, to see whether AD and FD still agree after n steps
    """

    steps: tuple[int, ...] = (1, 3, 10, 30, 100, 300, 1000)
    dtype: str = "float64"
    fd_check: bool = True

    def __post_init__(self):
        require(len(self.steps) > 0, "steps", "needs at least one rollout length")
        for i, n in enumerate(self.steps):
            require(n >= 1, f"steps[{i}]", f"must be >= 1, got {n}")
        require(list(self.steps) == sorted(set(self.steps)), "steps", f"must be strictly increasing, got {list(self.steps)}")
        require(self.dtype in DTYPES, "dtype", f"{self.dtype!r} is not one of {list(DTYPES)}")


@dataclass(frozen=True)
class Experiment:
    """One profile of the gradient check (see config.yaml for the meaning of each key)."""

    cases: tuple[Case, ...]
    dx: float = 0.05
    material: sph.Material = field(default_factory=lambda: sph.Material(rho_ref=1.0, eta=0.1, u_ref=1.0))
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    dtypes: tuple[str, ...] = DTYPES
    warmup_steps: int = 10
    loss_steps: int = 5
    eps_factor: float = 1e-3
    sweep_eps_factors: tuple[float, ...] = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
    sweep_directions: int = 32
    seed: int = 0
    fd_chunk: int = 64
    fd_vmap: int = 1
    extra_capacity: int = 8
    wall_layers: int = 3
    lid_velocity: float = 1.0
    fig1_dtypes: tuple[str, ...] = ("float64", "float32")
    growth: Growth = field(default_factory=Growth)

    def __post_init__(self):
        require_finite(self)
        require(len(self.cases) > 0, "cases", "needs at least one case")
        names = [c.name for c in self.cases]
        for i, n in enumerate(names):
            require(names.index(n) == i, f"cases[{i}].name", f"{n!r} appears twice")
        require(self.dx > 0 and abs(1.0 / self.dx - round(1.0 / self.dx)) < 1e-6, "dx",
                f"must divide the unit square into whole cells (1/dx integer), got {self.dx}")
        require(len(self.dtypes) > 0, "dtypes", "needs at least one precision")
        for i, d in enumerate(self.dtypes):
            require(d in DTYPES, f"dtypes[{i}]", f"{d!r} is not one of {list(DTYPES)}")
        require("float64" in self.dtypes, "dtypes", "float64 is the reference precision and must be listed")
        for i, d in enumerate(self.fig1_dtypes):
            require(d in self.dtypes, f"fig1_dtypes[{i}]", f"{d!r} is not one of dtypes {list(self.dtypes)}")
        require(self.warmup_steps >= 0, "warmup_steps", f"must be >= 0, got {self.warmup_steps}")
        require(self.loss_steps >= 1, "loss_steps", f"must be >= 1, got {self.loss_steps}")
        require(self.eps_factor > 0, "eps_factor", f"must be positive, got {self.eps_factor}")
        require(len(self.sweep_eps_factors) >= 2, "sweep_eps_factors", "needs at least two values")
        for i, e in enumerate(self.sweep_eps_factors):
            require(e > 0, f"sweep_eps_factors[{i}]", f"must be positive, got {e}")
        require(any(abs(e / self.eps_factor - 1) < 1e-9 for e in self.sweep_eps_factors), "sweep_eps_factors",
                f"must contain eps_factor ({self.eps_factor:g}) so the sweep shows the checked step")
        require(self.sweep_directions >= 1, "sweep_directions", f"must be >= 1, got {self.sweep_directions}")
        require(self.fd_chunk >= 1, "fd_chunk", f"must be >= 1, got {self.fd_chunk}")
        require(self.fd_vmap >= 1 and self.fd_chunk % self.fd_vmap == 0, "fd_vmap",
                f"must be >= 1 and divide fd_chunk ({self.fd_chunk}), got {self.fd_vmap}")
        require(self.extra_capacity >= 0, "extra_capacity", f"must be >= 0, got {self.extra_capacity}")
        require(self.wall_layers >= 1, "wall_layers", f"must be >= 1, got {self.wall_layers}")
        require(self.lid_velocity > 0, "lid_velocity", f"must be positive, got {self.lid_velocity}")

    @property
    def eps(self) -> float:
        """Finite-difference step of the main check, eps_factor * dx (paper: 1e-3 dx = 5e-5)."""
        return self.eps_factor * self.dx

    def numerics_for(self, dtype: str) -> sph.Numerics:
        """`numerics` with its dtype replaced by `dtype` (precision is chosen by `dtypes`)."""
        return replace(self.numerics, dtype=dtype)

    def case(self, name: str) -> Case:
        return next(c for c in self.cases if c.name == name)


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return load_profile(Experiment, path, profile, overrides)


# -- paths and code key (lab.layout) -------------------------------------------------------
STUDY = Study("gradcheck", HERE)
"""results/<profile>/gradcheck: the computed gradients and tables (metrics.csv among them); the code
key of settings.py and run.py with the sph modules they and the solver import."""
out_dir, metrics_path = STUDY.out_dir, STUDY.metrics_path


def check_path(results, case: str, dtype: str) -> Path:
    """Positions, AD and FD gradients and the eps sweep of one case and precision."""
    return out_dir(results) / f"{case}_{dtype}.npz"


def sweep_path(results) -> Path:
    return out_dir(results) / "sweep.csv"


def growth_path(results) -> Path:
    return out_dir(results) / "grad_growth.csv"


def fig_dir(results) -> Path:
    """results/<profile>/fig1: the figures and copies of the tables."""
    return Path(results) / "fig1"


# -- fingerprints ---------------------------------------------------------------------------------
def check_fingerprint(exp: Experiment, case: Case, dtype: str) -> str:
    keys = ("dx", "material", "warmup_steps", "loss_steps", "eps_factor", "sweep_eps_factors", "sweep_directions",
            "seed", "extra_capacity", "wall_layers", "lid_velocity")
    return digest({"case": to_mapping(case), "dtype": dtype, "numerics": to_mapping(exp.numerics_for(dtype)),
                   **{k: to_mapping(getattr(exp, k)) for k in keys}, "code": STUDY.code_hash("run.py")})
