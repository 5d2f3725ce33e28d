"""Momentum equation of weakly compressible SPH with the transport-velocity formulation; its terms.

Adami, Hu & Adams (2013), "A transport-velocity formulation for smoothed particle hydrodynamics",
J. Comput. Phys. 241:292, eqs. 8 and 13. Inter-particle volumes V = m / rho. Particle i's fields are
read from `i`, its neighbours' from `j` (`sph.views`); results are per particle of the block.
"""
from dataclasses import dataclass

from .pairs import sum_j
from .pvec import dot
from .rates import Rates


def _volume_weight(pp, i, j):
    """(V_i^2 + V_j^2) / m_i * (dW/dr) / r_ij, the common pair prefactor (B, K)."""
    return (i.vol ** 2 + j.vol ** 2) / i.mass * pp.f


def acceleration(pp, i, j, eta, tvf: bool):
    """du_i/dt of Adami 2013, eq. 8 (without body force):

    sum_j (V_i^2 + V_j^2)/m_i [ -p~_ij grad W_ij + 1/2 (A_i + A_j) . grad W_ij
                                + eta~_ij u_ij / r_ij dW/dr ],
    p~_ij = (rho_j p_i + rho_i p_j) / (rho_i + rho_j)  (eq. 7),
    A = rho u (v - u)  (the TVF stress, only when `tvf`),  eta~_ij = eta for a single fluid.
    u is the viscous velocity `u_visc`, v the stress's transport velocity `v_stress` (u~ on walls).
    """
    c = _volume_weight(pp, i, j)
    p_ij = (j.rho * i.p + i.rho * j.p) / (i.rho + j.rho)
    term = -p_ij * pp.dr + eta * (i.u_visc - j.u_visc)
    if tvf:
        # A . r_ij with A = rho u (x) (v - u): rho u ((v - u) . r_ij), averaged over i and j
        a_i = (i.rho * i.u_visc) * dot(i.v_stress - i.u_visc, pp.dr)
        a_j = (j.rho * j.u_visc) * dot(j.v_stress - j.u_visc, pp.dr)
        term = term + 0.5 * (a_i + a_j)
    return sum_j(c * term)


def background_acceleration(pp, i, j, p_b):
    """Background-pressure correction of the transport velocity, Adami 2013, eq. 13:

    d(v - u)_i/dt = -(p_b / m_i) sum_j (V_i^2 + V_j^2) dW/dr e_ij.
    """
    return -p_b * sum_j(_volume_weight(pp, i, j) * pp.dr)


def artificial_viscosity(pp, i, j, alpha: float, h: float, c_ref: float):
    """Monaghan (1992) artificial viscosity, as used for free-surface flows (Adami 2012, Sec. 4.3):
    du_i/dt = -sum_j m_j Pi_ij grad_i W_ij,  Pi_ij = -alpha h c_ref (u_ij . r_ij) / (rho_avg (r_ij^2 + 0.01 h^2)),
    applied to every pair (no approach switch, as in JAX-SPH), u = the viscous-term velocity.
    """
    u_ij = i.u_visc - j.u_visc
    rho_avg = 0.5 * (i.rho + j.rho)
    pi = -alpha * h * c_ref * dot(u_ij, pp.dr) / (rho_avg * (pp.d**2 + 0.01 * h * h))
    return sum_j(-(j.mass * pi * pp.f) * pp.dr)


@dataclass(frozen=True)
class Momentum:
    """Force-pass term: pressure gradient, viscosity and (with `tvf`) the TVF stress, eq. 8."""

    eta: float
    tvf: bool = False

    @property
    def reads(self) -> tuple:
        return ("r", "rho", "p", "mass", "vol", "u_visc") + (("v_stress",) if self.tvf else ())

    def __call__(self, pp, i, j):
        return Rates(dudt=acceleration(pp, i, j, self.eta, self.tvf))


@dataclass(frozen=True)
class BackgroundPressure:
    """Force-pass term: the TVF background-pressure acceleration of the transport velocity, eq. 13."""

    p_b: float
    reads = ("r", "mass", "vol")

    def __call__(self, pp, i, j):
        return Rates(dvdt=background_acceleration(pp, i, j, self.p_b))


@dataclass(frozen=True)
class ArtificialViscosity:
    """Force-pass term: Monaghan's artificial viscosity with coefficient `alpha`."""

    alpha: float
    h: float
    c_ref: float
    reads = ("r", "rho", "mass", "u_visc")

    def __call__(self, pp, i, j):
        return Rates(dudt=artificial_viscosity(pp, i, j, self.alpha, self.h, self.c_ref))
