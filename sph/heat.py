"""Thermal diffusion (Cleary 1998; Cleary & Monaghan 1999, J. Comput. Phys. 148:227, eq. 8).

  dT_i/dt = 1/c_p sum_j 4 m_j / (rho_i rho_j) kappa_i kappa_j/(kappa_i + kappa_j) (T_i - T_j)
            r_ij . grad_i W_ij / |r_ij|^2

For a single material kappa_i kappa_j/(kappa_i + kappa_j) = kappa/2, and r_ij . grad_i W_ij / |r_ij|^2
is the pair factor f = dW/dr / r of `sph.pairs` (neighbour lists exclude i itself, so r_ij > 0 and no
regularization is needed). The heat pass (`HeatPass`, step 6) integrates dT/dt on the free fluid
particles; the wall pass extrapolates the temperature to the walls (`sph.walls`).
"""
from dataclasses import dataclass
from typing import Optional

import jax.numpy as jnp

from .pairs import sum_j
from .passes import Pass
from .rates import Rates


@dataclass(frozen=True)
class TemperatureZone:
    """A slab lo <= r[axis] < hi where the fluid temperature is held at `T` (an inflow), or, with
    T = None, where dT/dt = 0 (an outflow that does not conduct back). Zones move with nothing:
    particles entering a zone take its rule, particles leaving it evolve freely again."""

    axis: int
    lo: float
    hi: float
    T: Optional[float] = None

    def inside(self, r):
        return (r[:, self.axis] >= self.lo) & (r[:, self.axis] < self.hi)


def temperature_rate(pp, i, j, kappa: float, c_p: float):
    """dT/dt of every particle of the block (B, 1)."""
    coef = j.mass / (i.rho * j.rho) * pp.f
    return (2.0 * kappa / c_p) * sum_j(coef * (i.T - j.T))


@dataclass(frozen=True)
class Conduction:
    """Force-pass term: heat conduction (Cleary 1998) into dT/dt."""

    kappa: float
    c_p: float
    reads = ("r", "mass", "rho", "T")

    def __call__(self, pp, i, j):
        return Rates(dTdt=temperature_rate(pp, i, j, self.kappa, self.c_p))


@dataclass(frozen=True)
class HeatPass(Pass):
    """Step 6: T^{n+1} = T^n + dt dT/dt on free fluid particles (not walls, not T_fixed); in an outflow
    zone (T None) dT/dt = 0, in an inflow zone T is held at the zone's value."""

    dt: float
    zones: tuple
    reads = ("r", "T", "dTdt")
    writes = ("T",)
    at_rest = False

    @classmethod
    def build(cls, scene, numerics, c):
        return cls(c.dt, tuple(scene.T_zones)) if scene.effects.heat else None

    def __call__(self, f, ctx, idx, step):
        free = jnp.asarray(ctx.fluid) & ~jnp.asarray(ctx.T_fixed)
        rate = f.dTdt
        for zone in self.zones:
            if zone.T is None:
                rate = jnp.where(zone.inside(f.r), 0.0, rate)
        T = f.T + self.dt * jnp.where(free, rate, 0.0)
        for zone in self.zones:
            if zone.T is not None:
                T = jnp.where(free & zone.inside(f.r), zone.T, T)
        return f.replace(T=T)
