"""Assemble `init_fn` / `step_fn` from a scene and its declared effects (jax-md style).

Time integration (one neighbour pass per step), semi-implicit (symplectic) Euler as in JAX-SPH:
  u^{n+1} = u^n + dt a^n
  v^{n+1} = u^{n+1} + dt/2 a_b^n        (TVF transport velocity, Adami 2013 eq. 13; v = u otherwise)
  r^{n+1} = r^n + dt v^{n+1}
  rho^{n+1}: summation at r^{n+1}, or rho^n + dt Drho/Dt(r^{n+1}, u^{n+1}) (continuity / Riemann),
             optionally re-initialized every N steps
  p^{n+1} = EoS(rho^{n+1});  a^{n+1}, a_b^{n+1} from the momentum equation at r^{n+1}.
Only the declared effects are traced into the step: a scene without TVF carries no TVF terms, one
without gravity adds no body force, one with summation density never evaluates the continuity sum.
"""
from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import density, momentum, riemann
from .config import Numerics
from .configtools import ConfigError
from .eos import RiemannEoS, TaitEoS
from .kernels import make_kernel
from .neighbors import NeighborSearch, make_neighbor_search
from .pairs import pair_geometry
from .precision import resolve
from .scene import Scene
from .state import ParticleState
from .timestep import time_step


@dataclass(frozen=True, eq=False)
class Solver:
    """Everything derived from (scene, numerics): constants, neighbour search and the two functions.

    init_fn() -> (state, nbrs)
    step_fn(state, nbrs, step) -> (state, nbrs)     `step` is the number of the step being taken
    state_at(r, u, nbrs) -> state                   traceable: the state init_fn builds at positions
                                                    `r`, velocities `u`, with a given neighbour list
    pairs_fn(r, nbrs) -> Pairs                      the pair geometry the step uses
    """

    scene: Scene
    numerics: Numerics
    kernel: object
    eos: object
    dt: float
    dt_limits: dict
    p_b: float
    dtype: object
    neighbors: NeighborSearch
    init_fn: Callable
    step_fn: Callable
    state_at: Callable
    pairs_fn: Callable

    def n_steps(self, t_end: float) -> int:
        return int(round(t_end / self.dt))


def build_solver(scene: Scene, numerics: Numerics = Numerics()) -> Solver:
    fx, mat = scene.effects, scene.material
    dtype = resolve(numerics.dtype)
    dim = scene.dim
    h = numerics.h_factor * scene.dx
    kernel = make_kernel(numerics.kernel, h, dim)
    c_ref = numerics.c_ref_factor * mat.u_ref
    p_ref = mat.rho_ref * c_ref**2 / (1.0 if fx.riemann else numerics.gamma)
    p_bg = numerics.p_bg_factor * p_ref
    if fx.riemann:
        eos = RiemannEoS(mat.rho_ref, c_ref, p_bg=p_bg)
    else:
        eos = TaitEoS(mat.rho_ref, c_ref, numerics.gamma, p_bg=p_bg)
    p_b = numerics.p_b_factor * p_ref
    gravity = None
    if fx.gravity is not None:
        if len(fx.gravity) != dim:
            raise ConfigError(f"effects.gravity: has {len(fx.gravity)} components but the scene is {dim}D")
        gravity = np.asarray(fx.gravity, dtype=float)
    g_max = float(np.linalg.norm(gravity)) if gravity is not None else 0.0
    limits = time_step(h, c_ref, mat.u_ref, mat.eta, mat.rho_ref, g_max, numerics.cfl)
    dt = numerics.dt if numerics.dt is not None else limits["dt"]
    skin = numerics.skin_factor * scene.dx
    nsearch = make_neighbor_search(scene.domain, kernel.cutoff, skin, numerics.capacity_multiplier)
    margin = kernel.cutoff + skin
    w0 = float(kernel.w(0.0))
    eta = mat.eta
    reinit = fx.density_reinit_every

    def pairs_of(r, nbrs):
        return pair_geometry(r, nbrs.idx, scene.domain, margin, kernel)

    def evolve_density(pairs, rho, p, u, mass, step):
        if fx.riemann:
            drhodt = riemann.continuity(pairs, rho, p, u, mass, c_ref)
        else:
            drhodt = density.continuity(pairs, rho, mass, u)
        rho = rho + dt * drhodt
        if reinit:
            rho = jax.lax.cond(step % reinit == 0,
                               lambda x: density.reinitialize(pairs, x, mass, w0), lambda x: x, rho)
        return rho

    def accelerations(pairs, rho, p, u, v, mass):
        if fx.riemann:
            dudt = riemann.acceleration(pairs, rho, p, u, mass, eta, c_ref, numerics.eta_limiter)
        else:
            dudt = momentum.acceleration(pairs, rho, p, u, v, mass, eta, fx.tvf)
        if gravity is not None:
            dudt = dudt + jnp.asarray(gravity, dtype)
        if fx.tvf:
            dvdt = momentum.background_acceleration(pairs, rho, mass, p_b)
        else:
            dvdt = jnp.zeros_like(dudt)
        return dudt, dvdt

    def state_at(r, u, nbrs):
        n = r.shape[0]
        mass = jnp.full((n,), mat.rho_ref * scene.dx**dim, dtype)
        pairs = pairs_of(r, nbrs)
        if fx.density_evolution:
            rho = jnp.full((n,), mat.rho_ref, dtype)
        else:
            rho = density.summation(pairs, mass, w0)
        p = eos.p(rho)
        dudt, dvdt = accelerations(pairs, rho, p, u, u, mass)
        return ParticleState(r=r, u=u, v=u, rho=rho, p=p, mass=mass,
                             tag=jnp.asarray(scene.tag, jnp.int32), dudt=dudt, dvdt=dvdt)

    def init_fn():
        r = jnp.asarray(scene.r, dtype)
        nbrs = nsearch.allocate(r)
        return state_at(r, jnp.asarray(scene.u, dtype), nbrs), nbrs

    def step_fn(state: ParticleState, nbrs, step):
        u = state.u + dt * state.dudt
        v = u + (0.5 * dt) * state.dvdt if fx.tvf else u
        r = scene.domain.shift(state.r, dt * v)
        nbrs = nsearch.update(r, nbrs)
        pairs = pairs_of(r, nbrs)
        if fx.density_evolution:
            rho = evolve_density(pairs, state.rho, state.p, u, state.mass, step)
        else:
            rho = density.summation(pairs, state.mass, w0)
        p = eos.p(rho)
        dudt, dvdt = accelerations(pairs, rho, p, u, v, state.mass)
        return state.replace(r=r, u=u, v=v, rho=rho, p=p, dudt=dudt, dvdt=dvdt), nbrs

    return Solver(scene=scene, numerics=numerics, kernel=kernel, eos=eos, dt=float(dt), dt_limits=limits,
                  p_b=p_b, dtype=dtype, neighbors=nsearch, init_fn=init_fn, step_fn=step_fn, state_at=state_at,
                  pairs_fn=pairs_of)
