"""`build_solver`: a scene and its numerics in, `init_fn` / `step_fn` out (jax-md style).

    constants = derive(scene, numerics)               kernel, EoS, c_ref, p_b, body force, dt
    refuse what cannot give a correct result          sph.checks (resolution; dt warning), sph.memory
    passes = choose_passes(scene, numerics, c)        sph.registry: the ordered pass list of the effects
    state_at, step_fn                                 sph.step: kick, drift, neighbours, the passes in order

Only the declared effects are traced into the step: a scene without TVF carries no TVF terms, one
without gravity adds no body force, one with summation density never evaluates the continuity sum,
one without walls has no wall pass, one without heat has no temperature field (state.T is None).
The solver carries a `StepGuard` (`solver.guard`, also `solver.step_fn.guard`) that the rollouts use
to refuse a step that takes a fluid particle out of the domain or blows up (`sph.diagnostics`).
"""
from dataclasses import dataclass
from functools import partial
from typing import Callable

import jax
import jax.numpy as jnp

from .checks import UnstableTimeStep, check_resolution, warn_fixed_dt  # noqa: F401  (sph.solver.UnstableTimeStep)
from .memory import InsufficientMemory, check_memory, neighbour_slots  # noqa: F401  (sph.solver.InsufficientMemory)
from .start_checks import StartInvariants, check_start
from .blocks import evaluate
from .config import Numerics
from .constants import derive
from .guard import StepGuard
from .neighbors import NeighborSearch, make_neighbor_search
from .passes import Context
from .registry import choose_passes
from .scene import Scene
from .step import state_at_fn, step_fn_of
from .views import Particles, whole_list_pairs


@dataclass(frozen=True, eq=False)
class Solver:
    """Everything derived from (scene, numerics): constants, neighbour search and the two functions.

    init_fn() -> (state, nbrs)
    step_fn(state, nbrs, step) -> (state, nbrs)     `step` is the number of the step being taken;
                                                    carries `step_fn.guard` (= `guard`)
    state_at(r, u, nbrs) -> state                   traceable: the state init_fn builds at positions
                                                    `r`, velocities `u`, with a given neighbour list
    passes                                          the ordered pass list of the step (sph.registry)
    pairs_fn(r, nbrs) -> Pairs                      the pair geometry of the whole list (for analysis)
    sweep_fn(term, nbrs, **fields)                  a term's per-particle results over the list, in
                                                    blocks, as a pass of the step evaluates it
                                                    (fields: sph.views.Particles, r required)
    c_ref                                           artificial sound speed c_ref_factor * u_ref
    guard                                           StepGuard (escape, speed limit c_ref, finiteness)
    memory_estimate                                 bytes a step needs at least (`check_memory`)
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
    passes: tuple = ()
    sweep_fn: Callable = None
    c_ref: float = float("nan")
    guard: StepGuard = None
    memory_estimate: int = 0

    def n_steps(self, t_end: float) -> int:
        return int(round(t_end / self.dt))


def build_solver(scene: Scene, numerics: Numerics = Numerics(), extra_terms=()) -> Solver:
    """The solver of `scene`; `extra_terms` are force-pass terms added after the declared ones
    (`sph.terms`: a term is `term(pairs, i, j) -> sph.rates.Rates`)."""
    c = derive(scene, numerics)
    check_resolution(scene, c.kernel.cutoff, c.skin, numerics)
    slots = neighbour_slots(c.kernel.cutoff, c.skin, scene.dx, scene.dim, numerics.capacity_multiplier)
    memory = check_memory(scene.n, scene.dim, slots, jnp.dtype(c.dtype).itemsize, f"scene {scene.name}", scene.dx)
    if numerics.dt is not None:
        warn_fixed_dt(scene, c.dt, c.limits)
    nsearch = make_neighbor_search(scene.domain, c.kernel.cutoff, c.skin, numerics.capacity_multiplier,
                                   backend=numerics.neighbor_search)
    passes, ctx = choose_passes(scene, numerics, c, extra_terms), Context.of(scene, c)
    state_at, step_fn = state_at_fn(scene, c, passes, ctx), step_fn_of(scene, c, passes, ctx, nsearch)

    def pairs_fn(r, nbrs):
        return whole_list_pairs(r, nbrs.idx, scene.domain, c.margin, c.kernel)

    def sweep_fn(term, nbrs, **fields):
        return evaluate(term, Particles(**fields), nbrs.idx, ctx.geometry)

    def init_fn():
        r = jnp.asarray(scene.r, c.dtype)
        nbrs = nsearch.allocate(r)
        vol = jnp.asarray(scene.particle_mass / scene.material.rho_ref, c.dtype)
        invariants = jax.jit(partial(sweep_fn, StartInvariants(c.kernel.cutoff, c.w0, c.h)))(nbrs, r=r, vol=vol)
        check_start(scene, invariants, c.kernel.cutoff, numerics)
        # jitted: op-by-op dispatch of the first state costs ~10x its compilation (29 s vs 3 s, ldc dx 0.02)
        return jax.jit(state_at)(r, jnp.asarray(scene.u, c.dtype), nbrs), nbrs

    guard = StepGuard(box=tuple(float(b) for b in scene.domain.box), periodic=tuple(bool(p) for p in scene.domain.periodic),
                      u_limit=c.c_ref, c_ref=c.c_ref, dt=c.dt, dt_limits=dict(c.limits),
                      fixed_dt=numerics.dt is not None, step_fn=step_fn)
    step_fn.guard = guard
    return Solver(scene=scene, numerics=numerics, kernel=c.kernel, eos=c.eos, dt=c.dt, dt_limits=c.limits,
                  p_b=c.p_b, dtype=c.dtype, neighbors=nsearch, init_fn=init_fn, step_fn=step_fn, state_at=state_at,
                  pairs_fn=pairs_fn, passes=passes, sweep_fn=sweep_fn, c_ref=c.c_ref, guard=guard, memory_estimate=memory)
