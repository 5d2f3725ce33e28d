"""Density: summation, continuity equation (evolution) and re-initialization."""
import jax.numpy as jnp

from .pairs import cdot


def summation(pairs, mass, w0):
    """Density summation rho_i = sum_j m_j W_ij, self term m_i W(0) included (Monaghan 1992, eq. 2.7)."""
    return mass * w0 + jnp.sum(pairs.gather(mass) * pairs.w, axis=1)


def continuity(pairs, rho, mass, u):
    """Continuity equation of Adami et al. (2013, eq. 2 in SPH form):

    drho_i/dt = rho_i sum_j (m_j / rho_j) (u_i - u_j) . grad_i W_ij
    """
    vol_j = pairs.gather(mass / rho)
    u_ij = pairs.own_vec(u) - pairs.gather_vec(u)
    return rho * jnp.sum(vol_j * cdot(u_ij, pairs.grad_w), axis=1)


def reinitialize(pairs, rho, mass, w0):
    """Density re-initialization by a Shepard (zeroth-order) filter, as used with the Riemann
    solver of Zhang, Hu & Adams (2017a):

    rho_i = sum_j m_j W_ij / sum_j (m_j / rho_j) W_ij   (self terms included).

    The denominator is capped at 1 so that particles with truncated support (free surface) keep
    their density instead of being inflated.
    """
    num = mass * w0 + jnp.sum(pairs.gather(mass) * pairs.w, axis=1)
    den = (mass / rho) * w0 + jnp.sum(pairs.gather(mass / rho) * pairs.w, axis=1)
    return num / jnp.minimum(den, 1.0)
