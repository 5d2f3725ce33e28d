"""The step as its algorithm box: kick and drift, the neighbour update, then the ordered pass list.

Semi-implicit (symplectic) Euler as in JAX-SPH, one neighbour update per step:
  1. u^{n+1} = u^n + dt a^n;  v^{n+1} = u^{n+1} + dt/2 a_b^n (TVF, Adami 2013 eq. 13; v = u otherwise);
     r^{n+1} = r^n + dt v^{n+1}  (walls keep their positions)            `kick_drift`
  then the passes of the scene (`sph.registry.PASSES`, each a map of the step's `Fields`):
  2. density:     rho^{n+1} by summation at r^{n+1}, or rho^n + dt Drho/Dt(r^{n+1}, u^{n+1});
                  every N steps the re-initialization (Zhang 2017a)
  3. pressure:    p^{n+1} = EoS(rho^{n+1})
  4. walls:       wall particles take p, rho, u~ and T from their fluid neighbours (Adami 2012)
  5. forces:      a^{n+1}, a_b^{n+1}, dT/dt, the sum of the force terms (zero on walls); surface tension
  6. heat:        T^{n+1} = T^n + dt dT/dt on free fluid particles (Cleary 1998), zones applied
`state_at` runs the same list on the state at given positions and velocities, without the passes
that advance in time (continuity, re-initialization, heat): an evolved density starts at rho_ref.
Each pair pass is one sweep over the neighbour list in cache-sized blocks of particles (`sph.blocks`).
"""
import jax.numpy as jnp
import numpy as np

from .fields import Fields
from .passes import run


def kick_drift(f: Fields, dt: float, tvf: bool, fluid, domain) -> Fields:
    """Step 1: kick u (and the transport velocity v with TVF), drift the fluid (`fluid` None: all move)."""
    u = f.u + dt * f.dudt
    v = u + (0.5 * dt) * f.dvdt if tvf else u
    if fluid is not None:
        v = jnp.where(jnp.asarray(fluid)[:, None], v, 0.0)
    return f.replace(r=domain.shift(f.r, dt * v), u=u, v=v)


def state_at_fn(scene, c, passes, ctx):
    """state_at(r, u, nbrs): the state at positions r and velocities u (the passes held `at_rest`)."""
    at_rest = tuple(p for p in passes if p.at_rest)
    walls = scene.effects.walls is not None

    def state_at(r, u, nbrs):
        zeros = jnp.zeros_like(u)
        f = Fields(r=r, u=u, v=jnp.where(jnp.asarray(scene.fluid_mask)[:, None], u, 0.0) if walls else u,
                   rho=jnp.full((scene.n,), scene.material.rho_ref, c.dtype),
                   p=jnp.zeros((scene.n,), c.dtype), mass=jnp.asarray(scene.particle_mass, c.dtype),
                   tag=jnp.asarray(scene.tag, jnp.int32), dudt=zeros, dvdt=zeros,
                   T=jnp.asarray(np.nan_to_num(scene.T), c.dtype) if scene.effects.heat else None)
        return run(at_rest, f, ctx, nbrs.idx, 0).state()

    return state_at


def step_fn_of(scene, c, passes, ctx, nsearch):
    """step_fn(state, nbrs, step) -> (state, nbrs): one step of the algorithm box above."""
    fluid = scene.fluid_mask if scene.effects.walls is not None else None

    def step_fn(state, nbrs, step):
        f = kick_drift(Fields.of(state), c.dt, scene.effects.tvf, fluid, scene.domain)    # 1.
        nbrs = nsearch.update(f.r, nbrs)
        return run(passes, f, ctx, nbrs.idx, step).state(), nbrs                          # 2.-6.

    return step_fn
