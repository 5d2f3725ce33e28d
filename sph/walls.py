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
The wall term (`WallExtrapolation`) evaluates these sums for every particle of a block, reading
particle i from `i` and its neighbours from `j` (`sph.views`); the wall pass (`WallPass`, step 4)
keeps the wall rows.
"""
from dataclasses import dataclass
from typing import Callable, Optional

import jax
import jax.numpy as jnp

from .pairs import sum_j
from .passes import Pass
from .pvec import PVec, dot


WEIGHT_FLOOR = 1e-6
"""Below WEIGHT_FLOOR * W(0), the derivative of 1 / (sum of fluid weights) is cut (`fluid_weights`)."""


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class FluidWeights:
    """Shepard weights of the fluid neighbours of every particle of a block.

    w_f   (B, K) W_ij where j is a fluid particle, 0 otherwise
    inv   (B, 1) 1 / sum_j w_f (0 where a particle has no fluid neighbour)
    """

    w_f: jax.Array
    inv: jax.Array


def fluid_weights(pp, j, floor=0.0) -> FluidWeights:
    """Shepard weights from `j.fluid` (1.0 for fluid neighbours).

    Where the fluid weights sum to at most `floor`, the value of 1 / sum is kept but its derivative
    is not propagated (the solver uses floor = WEIGHT_FLOOR * W(0) in float32): a wall particle that
    only touches the far tail of a fluid kernel has a sum of ~1e-30 in float32, and the derivative of
    1 / sum, -1 / sum^2, overflows to inf there, which turned the gradient of the whole rollout into
    NaN (inf * 0). Such a wall particle's own weight in any fluid sum is equally small, so the
    dropped term changes the fluid's gradients by less than the floor's relative size.
    """
    w_f = pp.w * j.fluid
    total = sum_j(w_f)
    some, live = total > 0, total > floor
    # the same value everywhere; below the floor the derivative of 1 / total is not propagated (the
    # differentiated branch never sees a tiny total, so its derivative stays finite where masked)
    tail = jax.lax.stop_gradient(1.0 / jnp.where(some, total, 1.0))
    inv = jnp.where(live, 1.0 / jnp.where(live, total, 1.0), tail)
    return FluidWeights(w_f=w_f, inv=jnp.where(some, inv, 0.0))


def extrapolate(fw: FluidWeights, x_j):
    """Shepard average over fluid neighbours of a gathered scalar (B, K) or PVec (eq. 22)."""
    return sum_j(fw.w_f * x_j) * fw.inv


def pressure(pp, fw: FluidWeights, i, j):
    """Wall pressure of eq. 27 (for every particle of the block; the caller keeps the wall rows),
    with the body force `i.g` at the particle (a_w = 0)."""
    hydro = sum_j((fw.w_f * j.rho) * pp.dr)  # sum_f rho_f r_wf W_wf
    return (sum_j(fw.w_f * j.p) + dot(i.g, hydro)) * fw.inv


def velocity(u_hat, u_w, normal=None):
    """Wall velocity for the viscous term: no slip (normal None, eq. 23) or free slip (normals);
    per-particle (N, dim) arrays."""
    if normal is None:
        return 2.0 * u_w - u_hat
    return u_hat + 2.0 * normal * jnp.sum(normal * (u_w - u_hat), axis=1, keepdims=True)


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class WallValues:
    """What the wall pass extrapolates from the fluid, per particle of the block: p (eq. 27),
    u^ (eq. 22) and, with heat, T."""

    p: jax.Array
    u_hat: PVec
    T: Optional[jax.Array] = None


@dataclass(frozen=True)
class WallExtrapolation:
    """Wall-pass term: the Shepard extrapolations of the generalized wall condition (Adami 2012);
    `floor` as in `fluid_weights`, `heat` extrapolates the temperature too."""

    floor: float = 0.0
    heat: bool = False

    @property
    def reads(self) -> tuple:
        return ("r", "fluid", "rho", "p", "u", "g") + (("T",) if self.heat else ())

    def __call__(self, pp, i, j):
        fw = fluid_weights(pp, j, self.floor)
        return WallValues(p=pressure(pp, fw, i, j), u_hat=extrapolate(fw, j.u),
                          T=extrapolate(fw, j.T) if self.heat else None)


@dataclass(frozen=True)
class WallPass(Pass):
    """Step 4: wall particles take p, rho = EoS^-1(p), the viscous velocity u~ (no slip, or free slip
    with `slip`) and, with heat, T (but where T is held fixed) from their fluid neighbours; the TVF
    stress sees u~ on walls too (`v_stress`). Fluid rows are unchanged."""

    term: Callable
    rho_of_p: Callable
    slip: bool
    writes = ("rho", "p", "u_visc", "v_stress", "T")

    @classmethod
    def build(cls, scene, numerics, c):
        fx = scene.effects
        if fx.walls is None:
            return None
        return cls(WallExtrapolation(c.weight_floor, fx.heat), c.eos.rho, fx.walls == "free_slip")

    @property
    def reads(self) -> tuple:
        return self.term.reads + ("v",)

    def __call__(self, f, ctx, idx, step):
        wall = jnp.asarray(ctx.wall)
        got = ctx.sweep(self.term, idx, f, self.term.reads)
        p = jnp.where(wall, got.p, f.p)
        normal = jnp.asarray(ctx.normal, ctx.c.dtype) if self.slip else None
        u_visc = jnp.where(wall[:, None], velocity(got.u_hat, f.u, normal), f.u)
        T = jnp.where(wall & ~jnp.asarray(ctx.T_fixed), got.T, f.T) if f.T is not None else None
        return f.replace(rho=jnp.where(wall, self.rho_of_p(p), f.rho), p=p, u_visc=u_visc,
                         v_stress=jnp.where(wall[:, None], u_visc, f.v), T=T)
