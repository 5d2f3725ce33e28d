"""Particle state as a registered dataclass pytree (jax-md style), no string-keyed dicts."""
from dataclasses import dataclass, fields, replace
from typing import Optional

import jax

FLUID, WALL, MOVING_WALL = 0, 1, 2
"""Particle tags: fluid, fixed wall, moving (prescribed-velocity) wall."""


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class ParticleState:
    """Fields of N particles in `dim` dimensions.

    r     (N, dim) positions
    u     (N, dim) momentum velocity
    v     (N, dim) transport (advection) velocity; v = u without TVF (Adami 2013, eq. 3)
    rho   (N,)     density
    p     (N,)     pressure
    mass  (N,)     mass
    tag   (N,)     int particle tag (FLUID, WALL, MOVING_WALL)
    dudt  (N, dim) acceleration of u from the last force evaluation (incl. body force)
    dvdt  (N, dim) background-pressure acceleration of the transport velocity (TVF; zeros otherwise)
    T     (N,)     temperature, only present when the scene declares heat (None otherwise)
    """

    r: jax.Array
    u: jax.Array
    v: jax.Array
    rho: jax.Array
    p: jax.Array
    mass: jax.Array
    tag: jax.Array
    dudt: jax.Array
    dvdt: jax.Array
    T: Optional[jax.Array] = None

    @property
    def n(self) -> int:
        return self.r.shape[0]

    @property
    def dim(self) -> int:
        return self.r.shape[1]

    def replace(self, **kw) -> "ParticleState":
        return replace(self, **kw)

    def field_names(self):
        return [f.name for f in fields(self) if getattr(self, f.name) is not None]
