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
from functools import partial

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


def make_step(scene: Scene, c: Constants, terms: Terms, nsearch):
    """(state_at, step_fn) of the scene: see `sph.solver.Solver`."""
    fx, dt, dtype = scene.effects, c.dt, c.dtype
    has_walls, n = terms.wall is not None, scene.n
    fluid, wall = jnp.asarray(scene.fluid_mask), jnp.asarray(scene.wall_mask)
    normal = jnp.asarray(scene.normal if scene.normal is not None else np.zeros_like(scene.r), dtype)
    t_fixed = jnp.asarray(scene.T_fixed if scene.T_fixed is not None else np.zeros(n, bool))
    geometry = partial(pair_geometry, domain=scene.domain, margin=c.margin, kernel=c.kernel)

    def sweep(term, idx, **fields):
        if has_walls:
            fields.update(wall=wall, normal=normal, fluid=fluid.astype(dtype))
        return blocks.evaluate(term, Particles(**fields), idx, geometry)

    def body_force(r):
        return c.force(r) if c.force is not None else jnp.zeros_like(r)

    def wall_pass(idx, r, rho, p, u, v, T):
        """Generalized wall condition: rho, p, u_visc (u~ on walls), v_stress (u~ on walls), T."""
        if not has_walls:
            return rho, p, u, v, T
        got = sweep(terms.wall, idx, r=r, rho=rho, p=p, u=u, T=T, g=body_force(r))
        p = jnp.where(wall, got.p, p)
        rho = jnp.where(wall, c.eos.rho(p), rho)
        u_visc = jnp.where(wall[:, None], walls.velocity(got.u_hat, u, normal if fx.walls == "free_slip" else None), u)
        T = jnp.where(wall & ~t_fixed, got.T, T) if T is not None else None
        return rho, p, u_visc, jnp.where(wall[:, None], u_visc, v), T

    def force_pass(idx, r, rho, p, u, u_visc, v_stress, mass, T):
        """dudt, dvdt, dTdt: the sum of the force terms (walls do not accelerate)."""
        def total(pp, i, j):
            out = terms.force[0](pp, i, j)
            for term in terms.force[1:]:
                out = out + term(pp, i, j)
            return out

        rates = sweep(total, idx, r=r, rho=rho, p=p, u=u, u_visc=u_visc, v_stress=v_stress, mass=mass,
                      vol=mass / rho, T=T, g=body_force(r))
        dudt = rates.dudt if rates.dudt is not None else jnp.zeros_like(r)
        dvdt = rates.dvdt if rates.dvdt is not None else jnp.zeros_like(dudt)
        if has_walls:
            dudt, dvdt = jnp.where(fluid[:, None], dudt, 0.0), jnp.where(fluid[:, None], dvdt, 0.0)
        return dudt, dvdt, rates.dTdt

    def heat_update(r, T, rate):
        free = fluid & ~t_fixed
        for zone in scene.T_zones:
            if zone.T is None:
                rate = jnp.where(zone.inside(r), 0.0, rate)
        T = T + dt * jnp.where(free, rate, 0.0)
        for zone in scene.T_zones:
            if zone.T is not None:
                T = jnp.where(free & zone.inside(r), zone.T, T)
        return T

    def state_at(r, u, nbrs):
        mass = jnp.full((n,), scene.material.rho_ref * scene.dx**scene.dim, dtype)
        T = jnp.asarray(np.nan_to_num(scene.T), dtype) if fx.heat else None
        v = jnp.where(fluid[:, None], u, 0.0) if has_walls else u
        if fx.density_evolution:
            rho = jnp.full((n,), scene.material.rho_ref, dtype)
        else:
            rho = sweep(terms.density, nbrs.idx, r=r, mass=mass)
        rho, p, u_visc, v_stress, T = wall_pass(nbrs.idx, r, rho, c.eos.p(rho), u, v, T)
        dudt, dvdt, _ = force_pass(nbrs.idx, r, rho, p, u, u_visc, v_stress, mass, T)
        return ParticleState(r=r, u=u, v=v, rho=rho, p=p, mass=mass, tag=jnp.asarray(scene.tag, jnp.int32),
                             dudt=dudt, dvdt=dvdt, T=T)

    def step_fn(state: ParticleState, nbrs, step):
        u = state.u + dt * state.dudt
        v = u + (0.5 * dt) * state.dvdt if fx.tvf else u
        if has_walls:
            v = jnp.where(fluid[:, None], v, 0.0)
        r = scene.domain.shift(state.r, dt * v)
        nbrs = nsearch.update(r, nbrs)
        idx, mass = nbrs.idx, state.mass
        rho = sweep(terms.density, idx, r=r, rho=state.rho, p=state.p, u=u, mass=mass, vol=mass / state.rho,
                    g=body_force(r))
        if terms.reinit is not None:
            rho = jax.lax.cond(step % terms.reinit_every == 0,
                               lambda x: sweep(terms.reinit, idx, r=r, rho=x, mass=mass, vol=mass / x), lambda x: x, rho)
        rho, p, u_visc, v_stress, T = wall_pass(idx, r, rho, c.eos.p(rho), u, v, state.T)
        dudt, dvdt, dTdt = force_pass(idx, r, rho, p, u, u_visc, v_stress, mass, T)
        if fx.heat:
            T = heat_update(r, T, dTdt)
        return state.replace(r=r, u=u, v=v, rho=rho, p=p, dudt=dudt, dvdt=dvdt, T=T), nbrs

    return state_at, step_fn
