"""The one state the passes of a step read and write: `ParticleState` plus the step's transients.

A step turns a `ParticleState` into `Fields` (`Fields.of`), runs the ordered pass list over it
(`sph.passes.run`), each pass mapping the fields to new ones, and returns `fields.state()`. The
transients live only within a step:

  u_visc    (N, dim) velocity of the viscous term: u, with u~ on wall particles (Adami 2012 eq. 23)
  v_stress  (N, dim) transport velocity of the TVF stress: v, with u~ on wall particles
  dTdt      (N,)     temperature rate of the force pass (heat)

Without walls no pass writes u_visc and v_stress; a pass that reads them gets u and v (`value`).
"""
from dataclasses import dataclass, fields
from typing import Optional

import jax

from .state import ParticleState

FALLBACK = {"u_visc": "u", "v_stress": "v"}
"""Transient fields that equal another field until a pass writes them (no walls: u~ = u)."""


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Fields(ParticleState):
    """ParticleState's fields (see there) and the transients of the module docstring."""

    u_visc: Optional[jax.Array] = None
    v_stress: Optional[jax.Array] = None
    dTdt: Optional[jax.Array] = None

    @classmethod
    def of(cls, state: ParticleState) -> "Fields":
        return cls(**{f.name: getattr(state, f.name) for f in fields(ParticleState)})

    def state(self) -> ParticleState:
        return ParticleState(**{f.name: getattr(self, f.name) for f in fields(ParticleState)})

    def value(self, name: str):
        """The field `name`, or the field it falls back to (FALLBACK) while no pass has written it."""
        x = getattr(self, name)
        return getattr(self, FALLBACK[name]) if x is None and name in FALLBACK else x
