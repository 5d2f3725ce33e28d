"""A scene: geometry (particles and domain), material and the effects it declares."""
from dataclasses import dataclass

import numpy as np

from .config import Effects, Material
from .configtools import ConfigError
from .domain import Domain
from .state import FLUID


@dataclass(frozen=True, eq=False)
class Scene:
    """Initial particles (`r`, `u`, `tag`, `mass` per particle) in a `domain`, plus what to simulate."""

    name: str
    dx: float
    domain: Domain
    material: Material
    effects: Effects
    r: np.ndarray
    u: np.ndarray
    tag: np.ndarray

    def __post_init__(self):
        n, dim = self.r.shape
        if dim != self.domain.dim:
            raise ConfigError(f"scene {self.name}: positions are {dim}D but the domain is {self.domain.dim}D")
        if self.u.shape != (n, dim) or self.tag.shape != (n,):
            raise ConfigError(f"scene {self.name}: u {self.u.shape} and tag {self.tag.shape} must match r {(n, dim)}")
        if not np.all(np.isfinite(self.r)) or not np.all(np.isfinite(self.u)):
            raise ConfigError(f"scene {self.name}: initial positions or velocities are not finite")
        box = np.array(self.domain.box)
        outside = np.any((self.r < 0) | (self.r >= box), axis=1)
        if outside.any():
            i = int(np.argmax(outside))
            raise ConfigError(f"scene {self.name}: particle {i} at {self.r[i]} lies outside the box [0, {box})")
        if not np.any(self.tag == FLUID):
            raise ConfigError(f"scene {self.name}: no fluid particles")

    @property
    def dim(self) -> int:
        return self.domain.dim

    @property
    def n(self) -> int:
        return self.r.shape[0]
