"""Density: summation, continuity equation (evolution) and re-initialization; the density-pass terms.

Each function reads particle i's fields from `i` and its neighbours' from `j` (`sph.views`) and
returns one value per particle of the block, shape (B, 1).
"""
from dataclasses import dataclass

import jax.numpy as jnp

from .pairs import sum_j
from .pvec import dot


def summation(pp, i, j, w0):
    """Density summation rho_i = sum_j m_j W_ij, self term m_i W(0) included (Monaghan 1992, eq. 2.7)."""
    return i.mass * w0 + sum_j(j.mass * pp.w)


def continuity(pp, i, j):
    """Continuity equation of Adami et al. (2013, eq. 2 in SPH form):

    drho_i/dt = rho_i sum_j (m_j / rho_j) (u_i - u_j) . grad_i W_ij
    """
    return i.rho * sum_j(j.vol * dot(i.u - j.u, pp.grad_w))


def reinitialize(pp, i, j, w0):
    """Density re-initialization by a Shepard (zeroth-order) filter, as used with the Riemann
    solver of Zhang, Hu & Adams (2017a):

    rho_i = sum_j m_j W_ij / sum_j (m_j / rho_j) W_ij   (self terms included).

    The denominator is capped at 1 so that particles with truncated support (free surface) keep
    their density instead of being inflated.
    """
    num = i.mass * w0 + sum_j(j.mass * pp.w)
    den = i.vol * w0 + sum_j(j.vol * pp.w)
    return num / jnp.minimum(den, 1.0)


@dataclass(frozen=True)
class Summation:
    """Density-pass term: rho^{n+1} by summation at the new positions."""

    w0: float

    def __call__(self, pp, i, j):
        return summation(pp, i, j, self.w0)


@dataclass(frozen=True)
class Continuity:
    """Density-pass term: rho^{n+1} = rho^n + dt drho/dt (Adami 2013, eq. 2)."""

    dt: float

    def __call__(self, pp, i, j):
        return i.rho + self.dt * continuity(pp, i, j)


@dataclass(frozen=True)
class Reinitialize:
    """Re-initialization-pass term: the Shepard-filtered density (Zhang 2017a)."""

    w0: float

    def __call__(self, pp, i, j):
        return reinitialize(pp, i, j, self.w0)
