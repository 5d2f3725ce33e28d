"""Density: summation, continuity equation (evolution) and re-initialization; the density passes.

Each function reads particle i's fields from `i` and its neighbours' from `j` (`sph.views`) and
returns one value per particle of the block, shape (B, 1). `DensityPass` (step 2) gives rho^{n+1} by
the scene's density term; `ReinitPass` re-initializes an evolved density every N steps.
"""
from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp

from .pairs import sum_j
from .passes import Pass
from .pvec import dot
from .riemann import RiemannContinuity


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
    reads = ("r", "mass")

    def __call__(self, pp, i, j):
        return summation(pp, i, j, self.w0)


@dataclass(frozen=True)
class Continuity:
    """Density-pass term: rho^{n+1} = rho^n + dt drho/dt (Adami 2013, eq. 2)."""

    dt: float
    reads = ("r", "rho", "u", "vol")

    def __call__(self, pp, i, j):
        return i.rho + self.dt * continuity(pp, i, j)


@dataclass(frozen=True)
class Reinitialize:
    """Re-initialization-pass term: the Shepard-filtered density (Zhang 2017a)."""

    w0: float
    reads = ("r", "mass", "vol")

    def __call__(self, pp, i, j):
        return reinitialize(pp, i, j, self.w0)


@dataclass(frozen=True)
class DensityPass(Pass):
    """Step 2: rho^{n+1} by summation at r^{n+1} (`Summation`), or rho^n + dt Drho/Dt(r^{n+1}, u^{n+1})
    (`Continuity`, `RiemannContinuity`). Summation evaluates the state (`state_at` runs it); an evolved
    density starts at rho_ref."""

    term: Callable
    writes = ("rho",)

    @classmethod
    def build(cls, scene, numerics, c):
        fx = scene.effects
        if fx.riemann:
            return cls(RiemannContinuity(c.dt, c.c_ref, c.eos.rho, fx.walls is not None))
        return cls(Continuity(c.dt) if fx.density_evolution else Summation(c.w0))

    @property
    def at_rest(self) -> bool:
        return isinstance(self.term, Summation)

    @property
    def reads(self) -> tuple:
        return self.term.reads

    def __call__(self, f, ctx, idx, step):
        return f.replace(rho=ctx.sweep(self.term, idx, f, self.reads))


@dataclass(frozen=True)
class ReinitPass(Pass):
    """Every `every` steps (step % every == 0), the Shepard re-initialization of the evolved density
    (Zhang 2017a; `effects.density_reinit_every`)."""

    term: Callable
    every: int
    writes = ("rho",)
    at_rest = False

    @classmethod
    def build(cls, scene, numerics, c):
        n = scene.effects.density_reinit_every
        return cls(Reinitialize(c.w0), n) if n else None

    @property
    def reads(self) -> tuple:
        return self.term.reads

    def __call__(self, f, ctx, idx, step):
        rho = jax.lax.cond(step % self.every == 0,
                           lambda x: ctx.sweep(self.term, idx, f.replace(rho=x), self.reads), lambda x: x, f.rho)
        return f.replace(rho=rho)
