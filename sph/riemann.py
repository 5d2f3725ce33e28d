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
Pair vectors are component-major (dim, N, K), see `sph.pairs`.
"""
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from .pairs import cdot


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class WallPairs:
    """Per-pair wall data for the one-sided Riemann problem.

    is_wall  (N, K) bool, neighbour j is a wall particle
    e        (dim, N, K) -n_j (direction from the fluid into the wall; unused where not a wall)
    dp       (N, K) hydrostatic pressure increment rho_i g_i . (r_j - r_i)
    """

    is_wall: jax.Array
    e: jax.Array
    dp: jax.Array


def wall_pairs(pairs, wall, normal, rho, g):
    """WallPairs from the (N,) wall mask, (N, dim) normals and (N, dim) body force."""
    dp = -rho[:, None] * cdot(pairs.own_vec(g), pairs.dr)
    return WallPairs(is_wall=pairs.gather(wall), e=-pairs.gather_vec(normal), dp=dp)


def _states(pairs, rho, p, u, walls, rho_of_p):
    """Direction e, velocities and left/right states of every pair."""
    e = -pairs.e
    rho_j, p_j = pairs.gather(rho), pairs.gather(p)
    if walls is not None:
        e = jnp.where(walls.is_wall[None], walls.e, e)
    u_i, u_j = pairs.own_vec(u), pairs.gather_vec(u)
    u_l, u_r = cdot(u_i, e), cdot(u_j, e)
    if walls is not None:
        u_r = jnp.where(walls.is_wall, 2.0 * u_r - u_l, u_r)
        p_wall = p[:, None] + walls.dp
        p_j = jnp.where(walls.is_wall, p_wall, p_j)
        rho_j = jnp.where(walls.is_wall, rho_of_p(p_wall), rho_j)
    return e, u_i, u_j, u_l, u_r, rho_j, p_j


def continuity(pairs, rho, p, u, mass, c_ref, walls=None, rho_of_p=None):
    """drho_i/dt = 2 rho_i sum_j (m_j/rho_j) (u_i - v*_ij) . grad_i W_ij   (eq. 8),
    v* = U* e + (u_avg - U_avg e)."""
    e, u_i, u_j, u_l, u_r, rho_j, p_j = _states(pairs, rho, p, u, walls, rho_of_p)
    rho_avg = 0.5 * (rho[:, None] + rho_j)
    u_avg_n = 0.5 * (u_l + u_r)
    u_star = u_avg_n + 0.5 * (p[:, None] - p_j) / (rho_avg * c_ref)
    v_star = u_star * e + (0.5 * (u_i + u_j) - u_avg_n * e)
    rel = cdot((u_i - v_star), pairs.grad_w)
    return 2.0 * rho * jnp.sum(pairs.gather(mass) / rho_j * rel, axis=1)


def acceleration(pairs, rho, p, u, mass, eta, c_ref, eta_limiter, u_visc=None, walls=None, rho_of_p=None):
    """du_i/dt = -2 sum_j m_j P*/(rho_i rho_j) grad_i W_ij            (eq. 9)
               + 2 sum_j m_j eta/(rho_i rho_j) u_ij/r_ij dW/dr          (viscous term, Zhang 2019 eq. 6).
    `eta_limiter` < 0 switches the limiter off (beta = c_ref). `u_visc` (default u) is the velocity
    of the viscous term (u~ on wall particles)."""
    _, u_i, u_j, u_l, u_r, rho_j, p_j = _states(pairs, rho, p, u, walls, rho_of_p)
    rho_avg = 0.5 * (rho[:, None] + rho_j)
    jump = u_l - u_r
    beta = c_ref if eta_limiter < 0 else jnp.minimum(eta_limiter * jnp.maximum(jump, 0.0), c_ref)
    p_star = 0.5 * (p[:, None] + p_j) + 0.5 * rho_avg * beta * jump
    coef = 2.0 * pairs.gather(mass) / (rho[:, None] * rho_j)
    if u_visc is not None:
        u_i, u_j = pairs.own_vec(u_visc), pairs.gather_vec(u_visc)
    return pairs.sum_vec(-(coef * p_star) * pairs.grad_w + (coef * eta * pairs.f) * (u_i - u_j))
