"""Settings of the 2D Taylor-Green experiment: config.yaml -> frozen, validated dataclasses, paths,
and the fingerprints that decide whether a cached result still matches its inputs."""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import sph
from sph.configtools import digest, load_profile, require, source_hash, to_mapping

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
CONFIG = HERE / "config.yaml"
KEEPABLE = ("velocity", "momentum_velocity", "density", "pressure")


@dataclass(frozen=True)
class Method:
    """A named solver variant: the effects its scene declares."""

    name: str
    effects: sph.Effects = field(default_factory=sph.Effects)


@dataclass(frozen=True)
class Relaxation:
    """Particle relaxation before the run (JAX-SPH's 'rlx' mode): a jittered lattice at rest,
    advanced with TVF and an EoS background pressure until the particles are evenly spread.

    steps         number of relaxation steps
    p_bg_factor   EoS background pressure / p_ref during relaxation
    noise_factor  standard deviation of the Gaussian lattice jitter / dx
    seed          seed of the jitter
    quench_every  set the velocity to zero every this many steps (0 = never, JAX-SPH's choice); the
                  quench removes the kinetic energy the relaxation keeps sloshing around, so the
                  particles settle instead of still moving at u_max ~ 0.025 after 5000 steps
    """

    steps: int = 5000
    p_bg_factor: float = 0.02
    noise_factor: float = 0.25
    seed: int = 123
    quench_every: int = 0

    def __post_init__(self):
        require(self.steps >= 0, "relaxation.steps", f"must be >= 0, got {self.steps}")
        require(self.noise_factor >= 0, "relaxation.noise_factor", f"must be >= 0, got {self.noise_factor}")
        require(self.quench_every >= 0, "relaxation.quench_every", f"must be >= 0, got {self.quench_every}")
        require(not self.quench_every or self.steps % self.quench_every == 0, "relaxation.quench_every",
                f"must divide relaxation.steps ({self.steps}), got {self.quench_every}")


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
        require(len(self.methods) > 0, "methods", "needs at least one method")
        names = [m.name for m in self.methods]
        for i, n in enumerate(names):
            require(names.index(n) == i, f"methods[{i}].name", f"{n!r} appears twice")
        require(len(self.dx) > 0, "dx", "needs at least one particle spacing")
        for i, dx in enumerate(self.dx):
            require(dx > 0 and abs(1.0 / dx - round(1.0 / dx)) < 1e-6, f"dx[{i}]",
                    f"must divide the unit square into whole cells (1/dx integer), got {dx}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
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
    """results/<profile>/tgv2d."""
    return Path(results) / "tgv2d"


def run_dir(results, method: str, dx: float) -> Path:
    return out_dir(results) / f"{method}_{dx_tag(dx)}"


def relaxed_path(results, dx: float) -> Path:
    return out_dir(results) / f"relaxed_{dx_tag(dx)}.npy"


def metrics_path(results) -> Path:
    return out_dir(results) / "metrics.csv"


# -- fingerprints ---------------------------------------------------------------------------------
def code_hash(*scripts: str) -> str:
    """Hash of the solver sources (sph/**/*.py), settings.py and the named scripts of this folder."""
    return source_hash(ROOT, [HERE / n for n in ("settings.py", *scripts)])


def relax_fingerprint(exp: Experiment, dx: float) -> str:
    return digest({"dx": dx, "material": to_mapping(exp.material), "numerics": to_mapping(exp.numerics),
                    "relaxation": to_mapping(exp.relaxation), "code": code_hash("relax.py")})


def run_fingerprint(exp: Experiment, method: Method, dx: float) -> str:
    return digest({"case": exp.case, "dx": dx, "method": to_mapping(method), "material": to_mapping(exp.material),
                    "numerics": to_mapping(exp.numerics), "t_end": exp.t_end, "frames": exp.frames,
                    "keep": list(exp.keep), "relax": relax_fingerprint(exp, dx), "code": code_hash("run.py")})
