"""Body forces per unit mass, evaluated at the particle positions (vectorized over particles).

A body force is a small frozen object: `force(r) -> (N, dim)` acceleration and `g_max`, the largest
magnitude it takes (for the body-force time-step limit, Adami 2012 eq. 25). A scene declares at
most one: `effects.gravity` (a constant vector) or `scene.body_force` (any of these objects).
"""
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from .rates import Rates


@dataclass(frozen=True)
class ConstantForce:
    """g, the same everywhere (gravity)."""

    g: tuple

    def __call__(self, r):
        return jnp.broadcast_to(jnp.asarray(self.g, r.dtype), r.shape)

    @property
    def g_max(self) -> float:
        return float(np.linalg.norm(self.g))


@dataclass(frozen=True)
class ReversePoiseuilleForce:
    """Piecewise-constant force along `axis`: +g where r[split_axis] < split, -g above.

    The driving force of the periodic reverse Poiseuille flow (Fatehi & Manzari 2011; JAX-SPH's RPF
    case uses g = 1, split at y = 1 in a 1 x 2 box).
    """

    g: float
    split: float
    axis: int = 0
    split_axis: int = 1

    def __call__(self, r):
        sign = jnp.where(r[:, self.split_axis] < self.split, 1.0, -1.0).astype(r.dtype)
        unit = jnp.zeros(r.shape[1], r.dtype).at[self.axis].set(1.0)
        return (self.g * sign)[:, None] * unit[None, :]

    @property
    def g_max(self) -> float:
        return abs(float(self.g))


@dataclass(frozen=True)
class BodyForce:
    """Force-pass term: the body force g at particle i (`i.g`), added to du/dt."""

    reads = ("r", "g")

    def __call__(self, pp, i, j):
        return Rates(dudt=i.g)
