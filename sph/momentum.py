"""Momentum equation of weakly compressible SPH with the transport-velocity formulation.

Adami, Hu & Adams (2013), "A transport-velocity formulation for smoothed particle hydrodynamics",
J. Comput. Phys. 241:292, eqs. 8 and 13. Inter-particle volumes V = m / rho. Pair vectors are
component-major (dim, N, K), see `sph.pairs`.
"""
from .pairs import cdot


def _volume_weight(pairs, rho, mass):
    """(V_i^2 + V_j^2) / m_i * (dW/dr) / r_ij, the common pair prefactor (N, K)."""
    vol = mass / rho
    return (vol[:, None] ** 2 + pairs.gather(vol) ** 2) / mass[:, None] * pairs.f


def acceleration(pairs, rho, p, u, v, mass, eta, tvf: bool):
    """du_i/dt of Adami 2013, eq. 8 (without body force):

    sum_j (V_i^2 + V_j^2)/m_i [ -p~_ij grad W_ij + 1/2 (A_i + A_j) . grad W_ij
                                + eta~_ij u_ij / r_ij dW/dr ],
    p~_ij = (rho_j p_i + rho_i p_j) / (rho_i + rho_j)  (eq. 7),
    A = rho u (v - u)  (the TVF stress, only when `tvf`),  eta~_ij = eta for a single fluid.
    """
    c = _volume_weight(pairs, rho, mass)
    rho_j, p_j = pairs.gather(rho), pairs.gather(p)
    p_ij = (rho_j * p[:, None] + rho[:, None] * p_j) / (rho[:, None] + rho_j)
    u_ij = pairs.own_vec(u) - pairs.gather_vec(u)
    term = -p_ij * pairs.dr + eta * u_ij
    if tvf:
        # A . r_ij with A = rho u (x) (v - u): rho u ((v - u) . r_ij), averaged over i and j
        ru, w = rho[:, None] * u, v - u
        a_i = pairs.own_vec(ru) * cdot(pairs.own_vec(w), pairs.dr)
        a_j = pairs.gather_vec(ru) * cdot(pairs.gather_vec(w), pairs.dr)
        term = term + 0.5 * (a_i + a_j)
    return pairs.sum_vec(c * term)


def background_acceleration(pairs, rho, mass, p_b):
    """Background-pressure correction of the transport velocity, Adami 2013, eq. 13:

    d(v - u)_i/dt = -(p_b / m_i) sum_j (V_i^2 + V_j^2) dW/dr e_ij.
    """
    c = _volume_weight(pairs, rho, mass)
    return -p_b * pairs.sum_vec(c * pairs.dr)


def artificial_viscosity(pairs, rho, u, mass, alpha: float, h: float, c_ref: float):
    """Monaghan (1992) artificial viscosity, as used for free-surface flows (Adami 2012, Sec. 4.3):
    du_i/dt = -sum_j m_j Pi_ij grad_i W_ij,  Pi_ij = -alpha h c_ref (u_ij . r_ij) / (rho_avg (r_ij^2 + 0.01 h^2)),
    applied to every pair (no approach switch, as in JAX-SPH), u = the viscous-term velocity.
    """
    u_ij = pairs.own_vec(u) - pairs.gather_vec(u)
    rho_avg = 0.5 * (rho[:, None] + pairs.gather(rho))
    pi = -alpha * h * c_ref * cdot(u_ij, pairs.dr) / (rho_avg * (pairs.d**2 + 0.01 * h * h))
    return pairs.sum_vec(-(pairs.gather(mass) * pi * pairs.f) * pairs.dr)
