"""Riemann SPH with the low-dissipation limiter (Zhang, Hu & Adams 2017b, J. Comput. Phys. 335:605).

Each pair (i, j) is a 1D Riemann problem along e = -e_ij (from i to j) with left state i and right
state j, solved with a linearized (acoustic) solver:
  U_L = u_i . e,  U_R = u_j . e,
  U*  = (U_L + U_R)/2 + (p_L - p_R) / (2 rho_avg c)                    (eq. 7)
  P*  = (p_L + p_R)/2 + rho_avg beta (U_L - U_R) / 2,                  (eq. 10)
  beta = min(eta_lim max(U_L - U_R, 0), c)   (dissipation limiter, eq. 11; beta = c without it)

Walls (Zhang 2017b, Sec. 3.3, one-sided Riemann problem): for a wall neighbour j with normal n_j
(pointing into the fluid) the problem runs along e = -n_j, and the right state mirrors the fluid:
  U_R = 2 U_w - U_L  (U_w = u_w . e, the prescribed wall velocity),
  p_R = p_L + rho_L g_i . (r_j - r_i),   rho_R = EoS^-1(p_R).
The viscous term uses the wall velocity u~ of the generalized wall condition (`sph.walls`).
Particle i's fields are read from `i`, its neighbours' from `j` (`sph.views`); wall neighbours are
those with `j.wall`, their normals `j.normal`, and `i.g` is the body force at i.
"""
from dataclasses import dataclass
from typing import Callable, Optional

import jax.numpy as jnp

from . import pvec
from .pairs import sum_j
from .pvec import dot
from .rates import Rates


def _states(pp, i, j, rho_of_p, walls: bool):
    """Direction e, velocities and left/right states of every pair (one-sided problems at walls)."""
    e = -pp.e
    rho_j, p_j = j.rho, j.p
    if walls:
        e = pvec.where(j.wall, -j.normal, e)
    u_i, u_j = i.u, j.u
    u_l, u_r = dot(u_i, e), dot(u_j, e)
    if walls:
        u_r = jnp.where(j.wall, 2.0 * u_r - u_l, u_r)
        p_wall = i.p + (-i.rho * dot(i.g, pp.dr))   # p_L + rho_L g_i . (r_j - r_i)
        p_j = jnp.where(j.wall, p_wall, p_j)
        rho_j = jnp.where(j.wall, rho_of_p(p_wall), rho_j)
    return e, u_i, u_j, u_l, u_r, rho_j, p_j


def continuity(pp, i, j, c_ref, rho_of_p=None, walls: bool = False):
    """drho_i/dt = 2 rho_i sum_j (m_j/rho_j) (u_i - v*_ij) . grad_i W_ij   (eq. 8),
    v* = U* e + (u_avg - U_avg e)."""
    e, u_i, u_j, u_l, u_r, rho_j, p_j = _states(pp, i, j, rho_of_p, walls)
    rho_avg = 0.5 * (i.rho + rho_j)
    u_avg_n = 0.5 * (u_l + u_r)
    u_star = u_avg_n + 0.5 * (i.p - p_j) / (rho_avg * c_ref)
    v_star = u_star * e + (0.5 * (u_i + u_j) - u_avg_n * e)
    rel = dot(u_i - v_star, pp.grad_w)
    return 2.0 * i.rho * sum_j(j.mass / rho_j * rel)


def acceleration(pp, i, j, eta, c_ref, eta_limiter, rho_of_p=None, walls: bool = False):
    """du_i/dt = -2 sum_j m_j P*/(rho_i rho_j) grad_i W_ij            (eq. 9)
               + 2 sum_j m_j eta/(rho_i rho_j) u_ij/r_ij dW/dr          (viscous term, Zhang 2019 eq. 6).
    `eta_limiter` < 0 switches the limiter off (beta = c_ref). With walls the viscous term uses
    `u_visc` (u~ on wall particles), the Riemann states u."""
    _, u_i, u_j, u_l, u_r, rho_j, p_j = _states(pp, i, j, rho_of_p, walls)
    rho_avg = 0.5 * (i.rho + rho_j)
    jump = u_l - u_r
    beta = c_ref if eta_limiter < 0 else jnp.minimum(eta_limiter * jnp.maximum(jump, 0.0), c_ref)
    p_star = 0.5 * (i.p + p_j) + 0.5 * rho_avg * beta * jump
    coef = 2.0 * j.mass / (i.rho * rho_j)
    if walls:
        u_i, u_j = i.u_visc, j.u_visc
    return sum_j(-(coef * p_star) * pp.grad_w + (coef * eta * pp.f) * (u_i - u_j))


@dataclass(frozen=True)
class RiemannContinuity:
    """Density-pass term: rho^{n+1} = rho^n + dt drho/dt of eq. 8 (one-sided at walls)."""

    dt: float
    c_ref: float
    rho_of_p: Optional[Callable] = None
    walls: bool = False

    @property
    def reads(self) -> tuple:
        return ("r", "rho", "p", "u", "mass") + (("wall", "normal", "g") if self.walls else ())

    def __call__(self, pp, i, j):
        return i.rho + self.dt * continuity(pp, i, j, self.c_ref, self.rho_of_p, self.walls)


@dataclass(frozen=True)
class RiemannMomentum:
    """Force-pass term: Riemann pressure with the dissipation limiter and viscosity, eq. 9."""

    eta: float
    c_ref: float
    eta_limiter: float
    rho_of_p: Optional[Callable] = None
    walls: bool = False

    @property
    def reads(self) -> tuple:
        return ("r", "rho", "p", "u", "mass") + (("wall", "normal", "g", "u_visc") if self.walls else ())

    def __call__(self, pp, i, j):
        return Rates(dudt=acceleration(pp, i, j, self.eta, self.c_ref, self.eta_limiter, self.rho_of_p, self.walls))
