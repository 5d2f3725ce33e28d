"""The force pass (step 5): du/dt, dv/dt and dT/dt as the sum of the force terms a scene declares.

A term is a small frozen object `term(pairs, i, j) -> sph.rates.Rates` (`sph.views`: particle i and
its neighbours j in a block) that names the fields it `reads`. `force_terms` picks them from the
scene's effects, in a fixed order; an effect the scene does not declare has no term, so its physics
is never traced. From outside, `build_solver(..., extra_terms=(MyTerm(...),))` adds force terms after
these (a term without `reads` is given every field the pass can provide).
"""
from dataclasses import dataclass, replace

import jax.numpy as jnp

from .forces import BodyForce
from .heat import Conduction
from .momentum import ArtificialViscosity, BackgroundPressure, Momentum
from .passes import Pass, reads_of
from .riemann import RiemannMomentum


def force_terms(scene, numerics, c) -> tuple:
    """Momentum (or Riemann momentum), body force, artificial viscosity, TVF background pressure, heat
    conduction: those the scene declares, in this order."""
    fx, mat, walls = scene.effects, scene.material, scene.effects.walls is not None
    if fx.riemann:
        force = [RiemannMomentum(mat.eta, c.c_ref, numerics.eta_limiter, c.eos.rho, walls)]
    else:
        force = [Momentum(mat.eta, fx.tvf)]
    force += [BodyForce()] if c.force is not None else []
    force += [ArtificialViscosity(fx.artificial_viscosity, c.h, c.c_ref)] if fx.artificial_viscosity else []
    force += [BackgroundPressure(c.p_b)] if fx.tvf else []
    force += [Conduction(mat.kappa, mat.c_p)] if fx.heat else []
    return tuple(force)


@dataclass(frozen=True)
class ForcePass(Pass):
    """Step 5: the sum of the force terms, in order, in one sweep; walls do not accelerate
    (`fluid_only`: dudt = dvdt = 0 on wall rows). dvdt is zero without a term that writes it (no TVF)."""

    terms: tuple
    fluid_only: bool
    writes = ("dudt", "dvdt", "dTdt")

    @classmethod
    def build(cls, scene, numerics, c):
        return cls(force_terms(scene, numerics, c), scene.effects.walls is not None)

    def adding(self, extra_terms) -> "ForcePass":
        """This pass with `extra_terms` summed after its own."""
        return replace(self, terms=self.terms + tuple(extra_terms))

    @property
    def reads(self) -> tuple:
        return reads_of(*self.terms)

    def total(self, pp, i, j):
        out = self.terms[0](pp, i, j)
        for term in self.terms[1:]:
            out = out + term(pp, i, j)
        return out

    def __call__(self, f, ctx, idx, step):
        rates = ctx.sweep(self.total, idx, f, self.reads)
        dudt = rates.dudt if rates.dudt is not None else jnp.zeros_like(f.r)
        dvdt = rates.dvdt if rates.dvdt is not None else jnp.zeros_like(dudt)
        if self.fluid_only:
            fluid = jnp.asarray(ctx.fluid)[:, None]
            dudt, dvdt = jnp.where(fluid, dudt, 0.0), jnp.where(fluid, dvdt, 0.0)
        return f.replace(dudt=dudt, dvdt=dvdt, dTdt=rates.dTdt)
