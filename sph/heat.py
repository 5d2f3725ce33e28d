"""Thermal diffusion (Cleary 1998; Cleary & Monaghan 1999, J. Comput. Phys. 148:227, eq. 8).

  dT_i/dt = 1/c_p sum_j 4 m_j / (rho_i rho_j) kappa_i kappa_j/(kappa_i + kappa_j) (T_i - T_j)
            r_ij . grad_i W_ij / |r_ij|^2

For a single material kappa_i kappa_j/(kappa_i + kappa_j) = kappa/2, and r_ij . grad_i W_ij / |r_ij|^2
is the pair factor f = dW/dr / r of `sph.pairs` (neighbour lists exclude i itself, so r_ij > 0 and no
regularization is needed). The Dirichlet (fixed-temperature) particles and the wall extrapolation of
the temperature are handled by the solver.
"""
from dataclasses import dataclass
from typing import Optional

from .pairs import sum_j
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

    def __call__(self, pp, i, j):
        return Rates(dTdt=temperature_rate(pp, i, j, self.kappa, self.c_p))
