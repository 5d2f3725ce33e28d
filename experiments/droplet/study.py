"""The droplet study: a 2D droplet at rest per resolution, its Laplace pressure jump and its spurious
currents (sph.cases.droplet; the protocol is lab.experiment's).

Per run (one resolution, dx = 1 / n_side):
  jump            mean over frames t >= average_from of p_inside - p_outside, each side averaged
                  more than one kernel support (3 h) away from the interface
  err_laplace     |jump / (sigma / R) - 1|, against Laplace's law (2D, curvature 1 / R)
  u_spurious      max |u| over the same frames (the exact solution is at rest)
  err_u_spurious  u_spurious / sqrt(sigma / (rho R)), the capillary velocity scale
"""
from dataclasses import dataclass, field

import numpy as np

from sph.cases import droplet
from sph.config import Numerics
from sph.errors import require, require_finite
from lab.configtools import from_mapping, to_mapping


@dataclass(frozen=True)
class Settings:
    """One profile of config.yaml (see its comments)."""

    n_side: tuple[int, ...]
    sigma: float = 1.0
    radius: float = 0.25
    eta: float = 0.05
    t_end: float = 3.0
    frames: int = 30
    average_from: float = 2.0
    numerics: dict = field(default_factory=dict)

    def __post_init__(self):
        require_finite(self)
        require(len(self.n_side) > 0, "n_side", "needs at least one resolution")
        for i, n in enumerate(self.n_side):
            require(n >= 12, f"n_side[{i}]", f"must be >= 12 (the kernel support of 3 dx fits the box twice), got {n}")
            require(self.n_side.index(n) == i, f"n_side[{i}]", f"{n} is listed twice")
        require(self.sigma > 0, "sigma", f"must be positive, got {self.sigma}")
        require(0 < self.radius < 0.5 - 3.0 / min(self.n_side), "radius",
                f"must leave a kernel support of outer fluid in the unit box, got {self.radius}")
        require(self.eta > 0, "eta", f"must be positive, got {self.eta}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        require(0 <= self.average_from < self.t_end, "average_from", f"must lie in [0, t_end), got {self.average_from}")
        recipe_numerics(self)


def recipe_numerics(s: Settings) -> Numerics:
    """The recipe's Numerics with the profile's overrides (an unknown key fails naming it)."""
    return from_mapping(Numerics, {**to_mapping(droplet.NUMERICS), **s.numerics}, "numerics")


@dataclass(frozen=True)
class Run:
    """One resolution: everything its numbers depend on (its cache key with the code)."""

    name: str
    n_side: int
    sigma: float
    radius: float
    eta: float
    t_end: float
    frames: int
    average_from: float
    numerics: Numerics
    method: str = droplet.METHOD


def runs(s: Settings) -> list:
    numerics = recipe_numerics(s)
    return [Run(f"n{n}", n, s.sigma, s.radius, s.eta, s.t_end, s.frames, s.average_from, numerics)
            for n in s.n_side]


def scene(run: Run):
    return droplet.scene(1.0 / run.n_side, run.sigma, run.radius, eta=run.eta), run.numerics


def metrics(run: Run, traj: dict) -> dict:
    dx, rho = 1.0 / run.n_side, 1.0
    late = traj["time"] >= run.average_from - 1e-9
    jumps = [np.subtract(*droplet.laplace_jump(r, p, (0.5, 0.5), run.radius, 3 * run.numerics.h_factor * dx))
             for r, p in zip(traj["position"][late], traj["pressure"][late])]
    exact = run.sigma / run.radius
    u = float(np.max(np.linalg.norm(traj["velocity"][late], axis=-1)))
    return {"err_laplace": abs(np.mean(jumps) / exact - 1.0), "err_u_spurious": u / np.sqrt(run.sigma / (rho * run.radius)),
            "jump": float(np.mean(jumps)), "jump_exact": exact, "u_spurious": u, "n_side": run.n_side,
            "radius_over_dx": run.radius / dx}
