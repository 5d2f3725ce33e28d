"""Riemann SPH with the low-dissipation limiter (Zhang, Hu & Adams 2017b, J. Comput. Phys. 335:605).

Each pair (i, j) is a 1D Riemann problem along e = -e_ij (from i to j) with left state i and right
state j, solved with a linearized (acoustic) solver:
  U_L = u_i . e,  U_R = u_j . e,
  U*  = (U_L + U_R)/2 + (p_L - p_R) / (2 rho_avg c)                    (eq. 7)
  P*  = (p_L + p_R)/2 + rho_avg beta (U_L - U_R) / 2,                  (eq. 10)
  beta = min(eta_lim max(U_L - U_R, 0), c)   (dissipation limiter, eq. 11; beta = c without it)
"""
import jax.numpy as jnp


def _left_right(pairs, u):
    e = -pairs.e
    u_j = pairs.gather(u)
    return e, u_j, jnp.sum(u[:, None, :] * e, axis=-1), jnp.sum(u_j * e, axis=-1)


def continuity(pairs, rho, p, u, mass, c_ref):
    """drho_i/dt = 2 rho_i sum_j (m_j/rho_j) (u_i - v*_ij) . grad_i W_ij   (eq. 8),
    v* = U* e + (u_avg - U_avg e)."""
    e, u_j, u_l, u_r = _left_right(pairs, u)
    rho_j, p_j = pairs.gather(rho), pairs.gather(p)
    rho_avg = 0.5 * (rho[:, None] + rho_j)
    u_avg_n = 0.5 * (u_l + u_r)
    u_star = u_avg_n + 0.5 * (p[:, None] - p_j) / (rho_avg * c_ref)
    v_star = u_star[..., None] * e + (0.5 * (u[:, None, :] + u_j) - u_avg_n[..., None] * e)
    rel = jnp.sum((u[:, None, :] - v_star) * pairs.grad_w, axis=-1)
    return 2.0 * rho * jnp.sum(pairs.gather(mass / rho) * rel, axis=1)


def acceleration(pairs, rho, p, u, mass, eta, c_ref, eta_limiter):
    """du_i/dt = -2 sum_j m_j P*/(rho_i rho_j) grad_i W_ij            (eq. 9)
               + 2 sum_j m_j eta/(rho_i rho_j) u_ij/r_ij dW/dr          (viscous term, Zhang 2019 eq. 6).
    `eta_limiter` < 0 switches the limiter off (beta = c_ref)."""
    _, u_j, u_l, u_r = _left_right(pairs, u)
    rho_j, p_j = pairs.gather(rho), pairs.gather(p)
    rho_avg = 0.5 * (rho[:, None] + rho_j)
    jump = u_l - u_r
    beta = c_ref if eta_limiter < 0 else jnp.minimum(eta_limiter * jnp.maximum(jump, 0.0), c_ref)
    p_star = 0.5 * (p[:, None] + p_j) + 0.5 * rho_avg * beta * jump
    m_j = pairs.gather(mass)
    coef = 2.0 * m_j / (rho[:, None] * rho_j)
    pressure = -(coef * p_star)[..., None] * pairs.grad_w
    u_ij = u[:, None, :] - u_j
    viscous = (coef * eta * pairs.f)[..., None] * u_ij
    return jnp.sum(pressure + viscous, axis=1)
