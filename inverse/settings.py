"""Settings of the inverse problem (paper Fig. 2): config.yaml -> frozen, validated dataclasses, paths
and the fingerprint that decides whether a finished optimization still matches its inputs."""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

import sph
from lab.configtools import load_profile, require, require_agree, require_finite, to_mapping
from lab.keys import digest
from lab.layout import Study

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
CONFIG = HERE / "config.yaml"
START_KINDS = ("cube", "random")
OPTIMIZER_KINDS = ("sgd", "adam")
LOSSES = ("mse", "rmse")


@dataclass(frozen=True)
class Case:
    """A target simulation: the block's lower-left corner `origin` in interior coordinates ([0, L]^2)."""

    name: str
    origin: tuple[float, ...]

    def __post_init__(self):
        require(len(self.origin) == 2, "origin", f"expected 2 entries (x, y), got {len(self.origin)}")


@dataclass(frozen=True)
class Start:
    """Where the optimizer starts.

    kind    "cube": the block at `origin` (interior coordinates), same particle order as the target;
            "random": every particle uniform in [margin, L - margin]^2, seeded by `seed`
    """

    name: str
    kind: str
    origin: Optional[tuple[float, ...]] = None
    seed: int = 0
    margin: float = 0.15

    def __post_init__(self):
        require(self.kind in START_KINDS, "kind", f"{self.kind!r} is not one of {START_KINDS}")
        require(self.kind != "cube" or self.origin is not None, "origin",
                f"start {self.name!r} of kind 'cube' needs an origin")
        require(self.origin is None or len(self.origin) == 2, "origin",
                f"expected 2 entries (x, y), got {len(self.origin or ())}")
        require(self.margin >= 0, "margin", f"must be >= 0, got {self.margin}")


@dataclass(frozen=True)
class Optimizer:
    """An optax optimizer: kind "sgd" (plain gradient descent) or "adam", constant learning rate.

    loss      the objective it descends: "mse" (mean squared error of the final positions, the
              default) or "rmse" (its square root, as JAX-SPH's notebook does; gradient
              dRMSE = dMSE / (2 RMSE)). The recorded loss is the MSE either way.
    max_step  clip every coordinate of an update to [-max_step, max_step] (optax.clip; a trust region
              against the large gradients of rollouts in which particles hit a wall); null = none
    """

    name: str
    kind: str
    learning_rate: float
    b1: float = 0.9
    b2: float = 0.999
    loss: str = "mse"
    max_step: Optional[float] = None

    def __post_init__(self):
        require(self.kind in OPTIMIZER_KINDS, "kind", f"{self.kind!r} is not one of {OPTIMIZER_KINDS}")
        require(self.learning_rate > 0, "learning_rate", f"must be positive, got {self.learning_rate}")
        require(0 <= self.b1 < 1 and 0 <= self.b2 < 1, "b1", "b1 and b2 must lie in [0, 1)")
        require(self.loss in LOSSES, "loss", f"{self.loss!r} is not one of {LOSSES}")
        require(self.max_step is None or self.max_step > 0, "max_step", f"must be positive or null, got {self.max_step}")


@dataclass(frozen=True)
class Experiment:
    """One profile (see config.yaml for the meaning of each key)."""

    cases: tuple[Case, ...]
    starts: tuple[Start, ...]
    optimizers: tuple[Optimizer, ...]
    t_end: float
    iterations: int
    dx: float = 0.05
    box_size: float = 1.0
    layers: int = 3
    cube_size: float = 0.3
    u0: tuple[float, ...] = (0.0, -0.5)
    material: sph.Material = field(default_factory=sph.Material)
    effects: sph.Effects = field(default_factory=sph.Effects)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    segments: int = 0
    clip_margin: float = 0.025
    extra_capacity: int = 16
    max_reallocations: int = 5
    path_optimizer: str = "gd"
    rmse_targets: tuple[float, ...] = ()

    def __post_init__(self):
        require_finite(self)
        require(self.dx > 0, "dx", f"must be positive, got {self.dx}")
        require(len(self.u0) == 2, "u0", f"expected 2 entries (x, y), got {len(self.u0)}")
        n_side = self.cube_size / self.dx
        require_agree(self.cube_size > 0 and abs(n_side - round(n_side)) < 1e-6, ("cube_size", "dx"),
                      f"must be a positive multiple of dx = {self.dx}, got {self.cube_size}")
        n_box = self.box_size / self.dx
        require_agree(abs(n_box - round(n_box)) < 1e-6, ("box_size", "dx"),
                      f"must be a multiple of dx = {self.dx}, got {self.box_size}")
        require(self.layers >= 1, "layers", f"must be >= 1, got {self.layers}")
        require(len(self.cases) > 0, "cases", "needs at least one case")
        require(len(self.starts) > 0, "starts", "needs at least one start")
        require(len(self.optimizers) > 0, "optimizers", "needs at least one optimizer")
        for what, items in (("cases", self.cases), ("starts", self.starts), ("optimizers", self.optimizers)):
            names = [x.name for x in items]
            for i, n in enumerate(names):
                require(names.index(n) == i, f"{what}[{i}].name", f"{n!r} appears twice")
        for i, c in enumerate(self.cases):
            self._check_block(c.origin, f"cases[{i}].origin")
        for i, s in enumerate(self.starts):
            if s.kind == "cube":
                self._check_block(s.origin, f"starts[{i}].origin")
            else:
                require(2 * s.margin < self.box_size, f"starts[{i}].margin",
                        f"leaves no room in a box of side {self.box_size}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.iterations >= 1, "iterations", f"must be >= 1, got {self.iterations}")
        require(self.segments >= 0, "segments", f"must be >= 0 (0 = no checkpointing), got {self.segments}")
        require(0 <= self.clip_margin < self.box_size / 2, "clip_margin", f"must lie in [0, box_size / 2), got {self.clip_margin}")
        require(self.extra_capacity >= 0, "extra_capacity", f"must be >= 0, got {self.extra_capacity}")
        require(self.max_reallocations >= 1, "max_reallocations", f"must be >= 1, got {self.max_reallocations}")
        require(self.effects.walls is not None, "effects.walls", "the block falls in a walled box: declare walls")
        require(self.path_optimizer in [o.name for o in self.optimizers], "path_optimizer",
                f"{self.path_optimizer!r} is not one of the optimizers {[o.name for o in self.optimizers]}")
        require(len(self.rmse_targets) in (0, len(self.cases)), "rmse_targets",
                f"needs one value per case ({len(self.cases)}) or none")

    def _check_block(self, origin, key):
        o = np.asarray(origin, float)
        require_agree(np.all(o >= 0) and np.all(o + self.cube_size <= self.box_size + 1e-12),
                      (key, "cube_size", "box_size"),
                      f"the block at {list(origin)} of side cube_size = {self.cube_size} does not fit into the box "
                      f"[0, {self.box_size}]^2")

    @property
    def n_fluid(self) -> int:
        return int(round(self.cube_size / self.dx)) ** 2

    def case(self, name: str) -> Case:
        return next(c for c in self.cases if c.name == name)


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return load_profile(Experiment, path, profile, overrides)


# -- paths and code key (lab.layout) -------------------------------------------------------
STUDY = Study("inverse", HERE)
"""results/<profile>/inverse: the optimization results of run.py (metrics.csv among them); the code
key of settings.py, scene.py and run.py with the sph modules they and the solver import."""
out_dir, metrics_path = STUDY.out_dir, STUDY.metrics_path


def paths_path(results) -> Path:
    """npz with the target states and every optimization path."""
    return out_dir(results) / "paths.npz"


def info_path(results) -> Path:
    return out_dir(results) / "run.json"


def fig_dir(results) -> Path:
    return Path(results) / "fig2"


# -- fingerprint ----------------------------------------------------------------------------------
def fingerprint(exp: Experiment) -> str:
    """Inputs of run.py: the whole profile (path_optimizer and rmse_targets only affect the plot and
    the report, but hashing them too is harmless) and the code: settings.py, scene.py, run.py and the
    sph modules they and the solver import (`STUDY.code_hash`)."""
    return digest({"experiment": to_mapping(exp), "code": STUDY.code_hash("scene.py", "run.py")})
