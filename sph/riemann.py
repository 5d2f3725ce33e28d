"""Riemann SPH with the low-dissipation limiter (Zhang, Hu & Adams 2017b, J. Comput. Phys. 335:605).

Each pair (i, j) is a 1D Riemann problem along e = -e_ij (from i to j) with left state i and right
state j, solved with a linearized (acoustic) solver:
  U_L = u_i . e,  U_R = u_j . e,
  U*  = (U_L + U_R)/2 + (p_L - p_R) / (2 rho_avg c)                    (eq. 7)
  P*  = (p_L + p_R)/2 + rho_avg beta (U_L - U_R) / 2,                  (eq. 10)
  beta = min(eta_lim max(U_L - U_R, 0), c)   (dissipation limiter, eq. 11; beta = c without it)
Pair vectors are component-major (dim, N, K), see `sph.pairs`.
"""
import jax.numpy as jnp

from .pairs import cdot


def _left_right(pairs, u):
    e = -pairs.e
    u_i, u_j = pairs.own_vec(u), pairs.gather_vec(u)
    return e, u_i, u_j, cdot(u_i, e), cdot(u_j, e)


def continuity(pairs, rho, p, u, mass, c_ref):
    """drho_i/dt = 2 rho_i sum_j (m_j/rho_j) (u_i - v*_ij) . grad_i W_ij   (eq. 8),
    v* = U* e + (u_avg - U_avg e)."""
    e, u_i, u_j, u_l, u_r = _left_right(pairs, u)
    rho_j, p_j = pairs.gather(rho), pairs.gather(p)
    rho_avg = 0.5 * (rho[:, None] + rho_j)
    u_avg_n = 0.5 * (u_l + u_r)
    u_star = u_avg_n + 0.5 * (p[:, None] - p_j) / (rho_avg * c_ref)
    v_star = u_star * e + (0.5 * (u_i + u_j) - u_avg_n * e)
    rel = cdot((u_i - v_star), pairs.grad_w)
    return 2.0 * rho * jnp.sum(pairs.gather(mass / rho) * rel, axis=1)


def acceleration(pairs, rho, p, u, mass, eta, c_ref, eta_limiter):
    """du_i/dt = -2 sum_j m_j P*/(rho_i rho_j) grad_i W_ij            (eq. 9)
               + 2 sum_j m_j eta/(rho_i rho_j) u_ij/r_ij dW/dr          (viscous term, Zhang 2019 eq. 6).
    `eta_limiter` < 0 switches the limiter off (beta = c_ref)."""
    _, u_i, u_j, u_l, u_r = _left_right(pairs, u)
    rho_j, p_j = pairs.gather(rho), pairs.gather(p)
    rho_avg = 0.5 * (rho[:, None] + rho_j)
    jump = u_l - u_r
    beta = c_ref if eta_limiter < 0 else jnp.minimum(eta_limiter * jnp.maximum(jump, 0.0), c_ref)
    p_star = 0.5 * (p[:, None] + p_j) + 0.5 * rho_avg * beta * jump
    coef = 2.0 * pairs.gather(mass) / (rho[:, None] * rho_j)
    return pairs.sum_vec(-(coef * p_star) * pairs.grad_w + (coef * eta * pairs.f) * (u_i - u_j))
