"""Surface tension between two phases: the continuum surface force (CSF, Brackbill, Kothe & Zemach
1992) in the SPH form of Morris (2000, Int. J. Numer. Meth. Fluids 33:333, Sec. 3).

The colour c is 1 on phase-1 particles and 0 on phase-0 ones (`Scene.phase`). With V = m / rho:

  n_i     = sum_j V_j (c_j - c_i) grad_i W_ij               colour gradient, points into phase 1
  N_i     = 1 where |n_i| > EPS / h (a reliable normal), else 0;  n^_i = n_i / |n_i| where N_i = 1
  kappa_i = -(div n^)_i = -sum_j N_i N_j V_j (n^_j - n^_i) . grad_i W_ij / (N_i V_i W(0) + sum_j N_i N_j V_j W_ij)
  du_i/dt += sigma kappa_i n_i / rho_i

(the denominator corrects the divergence for the normals missing from a particle's support, Morris
2000). A circle of radius R has kappa = 1 / R, and at rest the pressure jumps by sigma kappa across
the interface (Laplace's law). Capillary waves limit the time step (Brackbill 1992; Morris 2000):
dt <= cfl sqrt(rho_ref h^3 / (2 pi sigma)).
"""
import math
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from .errors import ConfigError
from .pairs import sum_j
from .passes import Pass
from .pvec import dot

EPS = 0.01
"""A normal is reliable where |n| > EPS / h (Morris 2000's epsilon): away from the interface the
colour gradient is round-off, and its direction noise."""


@dataclass(frozen=True)
class ColourGradient:
    """n_i = sum_j V_j (c_j - c_i) grad_i W_ij, with the colour c = `phase` (0 or 1)."""

    reads = ("r", "vol", "phase")

    def __call__(self, pp, i, j):
        return sum_j((j.vol * (j.phase - i.phase)) * pp.grad_w)


@dataclass(frozen=True)
class Curvature:
    """kappa_i = -(div n^)_i from the unit normals `aux` (zero where unreliable), normalised over the
    reliable part of the support (self term V_i W(0) included)."""

    w0: float
    reads = ("r", "vol", "aux")

    def __call__(self, pp, i, j):
        ok_i = (dot(i.aux, i.aux) > 0.5).astype(pp.w.dtype)
        both = ok_i * (dot(j.aux, j.aux) > 0.5).astype(pp.w.dtype)
        num = sum_j((both * j.vol) * dot(j.aux - i.aux, pp.grad_w))
        den = ok_i * i.vol * self.w0 + sum_j(both * j.vol * pp.w)
        return jnp.where(den > 0, -num / jnp.where(den > 0, den, 1.0), 0.0)


@dataclass(frozen=True)
class SurfaceTensionPass(Pass):
    """After the force pass: du/dt += sigma kappa n / rho (module docstring), `effects.surface_tension`
    = sigma. Needs phases 0 and 1 (`Scene.phase`); not combined with walls here."""

    sigma: float
    reliable: float
    w0: float
    reads = ("r", "rho", "mass", "vol", "phase", "dudt")
    writes = ("dudt",)

    @classmethod
    def build(cls, scene, numerics, c):
        sigma = scene.effects.surface_tension
        if not sigma:
            return None
        phases = set(np.unique(scene.phases).tolist())
        if phases != {0, 1}:
            raise ConfigError(f"effects.surface_tension: acts on the interface between phases 0 and 1, but "
                              f"scene {scene.name} has phases {sorted(phases)}: set scene.phase (1 inside the "
                              f"droplet, 0 around it)")
        if scene.effects.walls is not None:
            raise ConfigError("effects.surface_tension: not combined with walls here (the wall particles have "
                              "no colour); set effects.walls: null")
        return cls(float(sigma), EPS / c.h, c.w0)

    @staticmethod
    def dt_limits(scene, numerics, h) -> dict:
        sigma = scene.effects.surface_tension
        if not sigma:
            return {}
        return {"capillary": numerics.cfl * math.sqrt(scene.material.rho_ref * h**3 / (2.0 * math.pi * sigma))}

    def __call__(self, f, ctx, idx, step):
        n = ctx.sweep(ColourGradient(), idx, f, ColourGradient.reads)
        size2 = jnp.sum(n * n, axis=1)
        ok = size2 > self.reliable**2
        n_hat = jnp.where(ok[:, None], n / jnp.sqrt(jnp.where(ok, size2, 1.0))[:, None], 0.0)
        kappa = ctx.sweep(Curvature(self.w0), idx, f, ("r", "vol"), aux=n_hat)
        return f.replace(dudt=f.dudt + (self.sigma * kappa / f.rho)[:, None] * n)
