"""The step as its algorithm box: kick and drift, then the pair passes of the declared terms.

Semi-implicit (symplectic) Euler as in JAX-SPH, one neighbour update per step:
  1. u^{n+1} = u^n + dt a^n;  v^{n+1} = u^{n+1} + dt/2 a_b^n (TVF, Adami 2013 eq. 13; v = u otherwise);
     r^{n+1} = r^n + dt v^{n+1}  (walls keep their positions)
  2. density pass:   rho^{n+1} by summation at r^{n+1}, or rho^n + dt Drho/Dt(r^{n+1}, u^{n+1})
                     (continuity / Riemann); every N steps the re-initialization pass (Zhang 2017a)
  3. p^{n+1} = EoS(rho^{n+1})
  4. wall pass:      wall particles take p, rho, the viscous velocity u~ and T from their fluid
                     neighbours (Adami 2012, `sph.walls`)
  5. force pass:     a^{n+1}, a_b^{n+1}, dT/dt = the sum of the force terms (zero on walls)
  6. heat:           T^{n+1} = T^n + dt dT/dt on free fluid particles (Cleary 1998), zones applied
Each pass is one sweep over the neighbour list in cache-sized blocks of particles (`sph.blocks`).
"""
from dataclasses import dataclass
from functools import partial
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import blocks, walls
from .constants import Constants
from .pairs import pair_geometry
from .scene import Scene
from .state import ParticleState
from .terms import Terms
from .views import Particles


@dataclass(frozen=True, eq=False)
class Passes:
    """The pair passes of a scene (steps 2-6 above), each a sweep of its terms over the list `idx`."""

    scene: Scene
    c: Constants
    terms: Terms
    geometry: Callable

    @classmethod
    def of(cls, scene: Scene, c: Constants, terms: Terms) -> "Passes":
        return cls(scene, c, terms, partial(pair_geometry, domain=scene.domain, margin=c.margin, kernel=c.kernel))

    @property
    def has_walls(self) -> bool:
        return self.terms.wall is not None

    def masks(self):
        """fluid, wall, Dirichlet-temperature masks and wall normals (constants of the scene)."""
        sc = self.scene
        normal = sc.normal if sc.normal is not None else np.zeros_like(sc.r)
        t_fixed = sc.T_fixed if sc.T_fixed is not None else np.zeros(sc.n, bool)
        return jnp.asarray(sc.fluid_mask), jnp.asarray(sc.wall_mask), jnp.asarray(t_fixed), jnp.asarray(normal, self.c.dtype)

    def sweep(self, term, idx, **fields):
        if self.has_walls:
            fluid, wall, _, normal = self.masks()
            fields.update(wall=wall, normal=normal, fluid=fluid.astype(self.c.dtype))
        return blocks.evaluate(term, Particles(**fields), idx, self.geometry)

    def body_force(self, r):
        return self.c.force(r) if self.c.force is not None else jnp.zeros_like(r)

    def density(self, idx, r, rho, p, u, mass, step):
        """rho^{n+1} (step 2), re-initialized every `reinit_every` steps."""
        rho = self.sweep(self.terms.density, idx, r=r, rho=rho, p=p, u=u, mass=mass, vol=mass / rho, g=self.body_force(r))
        if self.terms.reinit is None:
            return rho
        return jax.lax.cond(step % self.terms.reinit_every == 0,
                            lambda x: self.sweep(self.terms.reinit, idx, r=r, rho=x, mass=mass, vol=mass / x),
                            lambda x: x, rho)

    def walls(self, idx, r, rho, p, u, v, T):
        """Generalized wall condition (step 4): rho, p, u_visc (u~ on walls), v_stress (u~ on walls), T."""
        if not self.has_walls:
            return rho, p, u, v, T
        _, wall, t_fixed, normal = self.masks()
        got = self.sweep(self.terms.wall, idx, r=r, rho=rho, p=p, u=u, T=T, g=self.body_force(r))
        p = jnp.where(wall, got.p, p)
        rho = jnp.where(wall, self.c.eos.rho(p), rho)
        slip = normal if self.scene.effects.walls == "free_slip" else None
        u_visc = jnp.where(wall[:, None], walls.velocity(got.u_hat, u, slip), u)
        T = jnp.where(wall & ~t_fixed, got.T, T) if T is not None else None
        return rho, p, u_visc, jnp.where(wall[:, None], u_visc, v), T

    def forces(self, idx, r, rho, p, u, u_visc, v_stress, mass, T):
        """dudt, dvdt, dTdt (step 5): the sum of the force terms, in order; walls do not accelerate."""
        def total(pp, i, j):
            out = self.terms.force[0](pp, i, j)
            for term in self.terms.force[1:]:
                out = out + term(pp, i, j)
            return out

        rates = self.sweep(total, idx, r=r, rho=rho, p=p, u=u, u_visc=u_visc, v_stress=v_stress, mass=mass,
                           vol=mass / rho, T=T, g=self.body_force(r))
        dudt = rates.dudt if rates.dudt is not None else jnp.zeros_like(r)
        dvdt = rates.dvdt if rates.dvdt is not None else jnp.zeros_like(dudt)
        if self.has_walls:
            fluid = self.masks()[0][:, None]
            dudt, dvdt = jnp.where(fluid, dudt, 0.0), jnp.where(fluid, dvdt, 0.0)
        return dudt, dvdt, rates.dTdt

    def heat(self, r, T, rate):
        """T^{n+1} (step 6) on free fluid particles; outflow zones freeze, inflow zones hold T."""
        fluid, _, t_fixed, _ = self.masks()
        free = fluid & ~t_fixed
        zones = self.scene.T_zones
        for zone in zones:
            if zone.T is None:
                rate = jnp.where(zone.inside(r), 0.0, rate)
        T = T + self.c.dt * jnp.where(free, rate, 0.0)
        for zone in zones:
            if zone.T is not None:
                T = jnp.where(free & zone.inside(r), zone.T, T)
        return T


def state_at_fn(passes: Passes):
    """state_at(r, u, nbrs): the state at positions r and velocities u (steps 2-5 without a step)."""
    sc, c, fx = passes.scene, passes.c, passes.scene.effects

    def state_at(r, u, nbrs):
        fluid = jnp.asarray(sc.fluid_mask)
        mass = jnp.full((sc.n,), sc.material.rho_ref * sc.dx**sc.dim, c.dtype)
        T = jnp.asarray(np.nan_to_num(sc.T), c.dtype) if fx.heat else None
        v = jnp.where(fluid[:, None], u, 0.0) if passes.has_walls else u
        if fx.density_evolution:
            rho = jnp.full((sc.n,), sc.material.rho_ref, c.dtype)
        else:
            rho = passes.sweep(passes.terms.density, nbrs.idx, r=r, mass=mass)
        rho, p, u_visc, v_stress, T = passes.walls(nbrs.idx, r, rho, c.eos.p(rho), u, v, T)
        dudt, dvdt, _ = passes.forces(nbrs.idx, r, rho, p, u, u_visc, v_stress, mass, T)
        return ParticleState(r=r, u=u, v=v, rho=rho, p=p, mass=mass, tag=jnp.asarray(sc.tag, jnp.int32),
                             dudt=dudt, dvdt=dvdt, T=T)

    return state_at


def step_fn_of(passes: Passes, nsearch):
    """step_fn(state, nbrs, step) -> (state, nbrs): one step of the algorithm box above."""
    sc, dt, fx = passes.scene, passes.c.dt, passes.scene.effects

    def step_fn(state: ParticleState, nbrs, step):
        u = state.u + dt * state.dudt                                   # 1. kick and drift
        v = u + (0.5 * dt) * state.dvdt if fx.tvf else u
        if passes.has_walls:
            v = jnp.where(jnp.asarray(sc.fluid_mask)[:, None], v, 0.0)
        r = sc.domain.shift(state.r, dt * v)
        nbrs = nsearch.update(r, nbrs)
        rho = passes.density(nbrs.idx, r, state.rho, state.p, u, state.mass, step)              # 2.
        rho, p, u_visc, v_stress, T = passes.walls(nbrs.idx, r, rho, passes.c.eos.p(rho), u, v, state.T)  # 3., 4.
        dudt, dvdt, dTdt = passes.forces(nbrs.idx, r, rho, p, u, u_visc, v_stress, state.mass, T)  # 5.
        if fx.heat:
            T = passes.heat(r, T, dTdt)                                 # 6.
        return state.replace(r=r, u=u, v=v, rho=rho, p=p, dudt=dudt, dvdt=dvdt, T=T), nbrs

    return step_fn
