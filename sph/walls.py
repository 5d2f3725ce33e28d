"""Generalized wall boundary condition (Adami, Hu & Adams 2012, J. Comput. Phys. 231:7057).

Wall particles (several layers, tags WALL and MOVING_WALL) keep their positions and their
prescribed velocity u_w (zero for a fixed wall, e.g. the lid speed for a moving wall). Before every
force evaluation each wall particle w takes its state from its fluid neighbours f by Shepard sums:

  p_w   = [ sum_f p_f W_wf + (g_w - a_w) . sum_f rho_f r_wf W_wf ] / sum_f W_wf       (eq. 27)
  rho_w = EoS^-1(p_w)                                                                (eq. 28)
  u^_w  = sum_f u_f W_wf / sum_f W_wf                                                (eq. 22)
  no slip:   u~_w = 2 u_w - u^_w                                                     (eq. 23)
  free slip: u~_w = u^_w + 2 n_w (n_w . (u_w - u^_w))  (only the normal part is mirrored)

with a_w = 0 (walls do not accelerate). u~_w enters only the viscous term and the TVF stress; the
continuity equation sees the prescribed u_w. A wall particle with no fluid neighbour gets p_w = 0
and u^_w = 0 (it does not act on any fluid particle either, by kernel symmetry).
Pair vectors are component-major (dim, N, K), see `sph.pairs`.
"""
from dataclasses import dataclass

import jax
import jax.numpy as jnp


WEIGHT_FLOOR = 1e-6
"""Below WEIGHT_FLOOR * W(0), the derivative of 1 / (sum of fluid weights) is cut (`fluid_weights`)."""


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class FluidWeights:
    """Shepard weights of the fluid neighbours of every particle.

    w_f   (N, K) W_ij where j is a fluid particle, 0 otherwise
    inv   (N,)   1 / sum_j w_f (0 where a particle has no fluid neighbour)
    """

    w_f: jax.Array
    inv: jax.Array


def fluid_weights(pairs, fluid, floor=0.0) -> FluidWeights:
    """`fluid` is a (N,) 0/1 float array (1 for fluid particles).

    Where the fluid weights sum to at most `floor`, the value of 1 / sum is kept but its derivative
    is not propagated (the solver uses floor = WEIGHT_FLOOR * W(0)): a wall particle that only
    touches the far tail of a fluid kernel has a sum of ~1e-30 in float32, and the derivative of
    1 / sum, -1 / sum^2, overflows to inf there, which turned the gradient of the whole rollout into
    NaN (inf * 0). Such a wall particle's own weight in any fluid sum is equally small, so the
    dropped term changes the fluid's gradients by less than the floor's relative size.
    """
    w_f = pairs.w * pairs.gather(fluid)
    total = jnp.sum(w_f, axis=1)
    some, live = total > 0, total > floor
    # the same value everywhere; below the floor the derivative of 1 / total is not propagated (the
    # differentiated branch never sees a tiny total, so its derivative stays finite where masked)
    tail = jax.lax.stop_gradient(1.0 / jnp.where(some, total, 1.0))
    inv = jnp.where(live, 1.0 / jnp.where(live, total, 1.0), tail)
    return FluidWeights(w_f=w_f, inv=jnp.where(some, inv, 0.0))


def extrapolate(pairs, fw: FluidWeights, x):
    """Shepard average of a per-particle scalar over fluid neighbours (eq. 22): (N,) -> (N,)."""
    return jnp.sum(fw.w_f * pairs.gather(x), axis=1) * fw.inv


def extrapolate_vec(pairs, fw: FluidWeights, x):
    """Shepard average of a per-particle vector over fluid neighbours: (N, dim) -> (N, dim)."""
    return pairs.sum_vec(fw.w_f * pairs.gather_vec(x)) * fw.inv[:, None]


def pressure(pairs, fw: FluidWeights, p, rho, g_w):
    """Wall pressure of eq. 27 (for every particle; the caller keeps the wall rows). `g_w` (N, dim)
    is the body force at each particle (a_w = 0)."""
    hydro = pairs.sum_vec((fw.w_f * pairs.gather(rho)) * pairs.dr)  # sum_f rho_f r_wf W_wf
    return (jnp.sum(fw.w_f * pairs.gather(p), axis=1) + jnp.sum(g_w * hydro, axis=1)) * fw.inv


def velocity(u_hat, u_w, normal=None):
    """Wall velocity for the viscous term: no slip (normal None, eq. 23) or free slip (normals)."""
    if normal is None:
        return 2.0 * u_w - u_hat
    return u_hat + 2.0 * normal * jnp.sum(normal * (u_w - u_hat), axis=1, keepdims=True)
