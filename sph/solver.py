"""Assemble `init_fn` / `step_fn` from a scene and its declared effects (jax-md style).

Time integration (one neighbour pass per step), semi-implicit (symplectic) Euler as in JAX-SPH:
  u^{n+1} = u^n + dt a^n
  v^{n+1} = u^{n+1} + dt/2 a_b^n        (TVF transport velocity, Adami 2013 eq. 13; v = u otherwise)
  r^{n+1} = r^n + dt v^{n+1}
  rho^{n+1}: summation at r^{n+1}, or rho^n + dt Drho/Dt(r^{n+1}, u^{n+1}) (continuity / Riemann),
             optionally re-initialized every N steps
  p^{n+1} = EoS(rho^{n+1});  a^{n+1}, a_b^{n+1} from the momentum equation at r^{n+1}.
  walls (Adami 2012): after the density, wall particles take p, rho and the viscous velocity u~
             from their fluid neighbours (`sph.walls`); walls keep their positions and velocity.
  heat (Cleary 1998): T^{n+1} = T^n + dt dT/dt(r^{n+1}, rho^{n+1}, T^n) on free (non-Dirichlet) fluid
             particles; non-Dirichlet wall particles take the Shepard-extrapolated fluid temperature.
Only the declared effects are traced into the step: a scene without TVF carries no TVF terms, one
without gravity adds no body force, one with summation density never evaluates the continuity sum,
one without walls has no wall pass, one without heat has no temperature field (state.T is None).

The pair work of a step (density, walls, accelerations, heat) is one function of the neighbour list,
written over the whole (N, K) list and evaluated in cache-sized blocks of particles by
`sph.pairs.row_blocked` (same operations per particle, results equal to round-off; 1.4x faster
in 3D and 2.5x less memory at 50^3 than over the whole list); only a density re-initialization splits
it, around its `lax.cond`.

`build_solver` refuses what cannot give a correct result, before anything large is allocated
(`check_resolution`, `check_memory`): a periodic side shorter than twice the kernel support (a
particle would meet its own image), a fluid narrower than the support, walls thinner than the
support, and a run whose particles and neighbour slots cannot fit in the available memory. A fixed
`numerics.dt` above the stability limits is reported with an `UnstableTimeStep` warning. The
solver carries a `StepGuard` (`solver.guard`, also `solver.step_fn.guard`) that the rollouts use to
refuse a step that takes a fluid particle out of the domain or blows up (`sph.diagnostics`).
"""
import math
import warnings
from dataclasses import dataclass
from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import density, heat, momentum, riemann, walls
from . import pairs as pairs_module
from .config import Numerics
from .errors import ConfigError
from .diagnostics import StepGuard
from .eos import RiemannEoS, TaitEoS
from .forces import ConstantForce
from .kernels import make_kernel
from .neighbors import NeighborSearch, make_neighbor_search
from .pairs import pair_geometry
from .precision import resolve
from .scene import Scene
from .state import ParticleState
from .timestep import time_step



class UnstableTimeStep(UserWarning):
    """A fixed numerics.dt exceeds one of the time-step limits (sph.timestep)."""


class InsufficientMemory(ConfigError, MemoryError):
    """The run would need more memory than is available (estimated before allocating)."""


# bytes per neighbour slot that a step needs at least: the int32 index, the pair geometry
# (dim + 3 floats: dr, |r|, W, dW/dr / r, sph.pairs) and ~4 more floats of pair terms in the physics;
# measured peak temporaries of a jitted step are 2-4x this (XLA memory_analysis, dx 0.02, 2D)
def _bytes_per_slot(dim: int, itemsize: int) -> int:
    return 4 + 1 + (dim + 3 + 4) * itemsize


def neighbour_slots(cutoff: float, skin: float, dx: float, dim: int, capacity_multiplier: float) -> int:
    """Neighbour slots per particle a list allocates: particles within cutoff + skin of a lattice
    (a disc / ball of that radius over dx^dim), times the capacity multiplier."""
    rc = (cutoff + skin) / dx
    ball = math.pi * rc**2 if dim == 2 else (4.0 / 3.0 * math.pi * rc**3 if dim == 3 else 2 * rc)
    return int(math.ceil(capacity_multiplier * ball))


def available_memory() -> tuple:
    """(bytes available to the arrays of a run, where): the default JAX device's free memory on an
    accelerator, the host's available memory (psutil) on CPU."""
    dev = jax.devices()[0]
    if dev.platform != "cpu":
        try:
            stats = dev.memory_stats() or {}
            if "bytes_limit" in stats:
                return int(stats["bytes_limit"] - stats.get("bytes_in_use", 0)), f"{dev.platform} device memory"
        except Exception:  # noqa: BLE001  (memory_stats is optional per backend)
            pass
    import psutil

    return int(psutil.virtual_memory().available), "available host memory"


def check_memory(n: int, dim: int, slots: int, itemsize: int, where: str, dx: float) -> int:
    """Raise InsufficientMemory if `n` particles with `slots` neighbour slots each need more than
    the available memory; returns the estimate (bytes, a lower bound: fields + the list + the pair
    terms of one step)."""
    per_particle = (6 * dim + 6) * itemsize + slots * _bytes_per_slot(dim, itemsize)
    need = n * per_particle
    avail, what = available_memory()
    if need > avail:
        raise InsufficientMemory(
            f"{where}: {n:,} particles (dx = {dx:g}) with {slots} neighbour slots each need at least "
            f"{need / 2**30:.3g} GiB (about {per_particle / 1024:.3g} KiB per particle: fields, neighbour list, "
            f"pair terms), but only {avail / 2**30:.3g} GiB {what} is free: use a larger dx")
    return need


def check_resolution(scene: Scene, cutoff: float, skin: float, numerics: Numerics) -> None:
    """Named ConfigErrors for a scene the kernel cannot resolve (see the module docstring):

    periodic side L < 2 cutoff      the minimum image is no longer unique within the support: a
                                    particle would interact with its own image or twice with a neighbour
    (a fluid body narrower than the support is allowed: a droplet, a jet or a single particle thrown
    at a wall is legitimate physics, resolved or not)
    walled box < 3 cutoff           with walls, a non-periodic side holds less than two wall layers of
                                    the support's thickness and one support of fluid (a cavity at dx 1)
    walls thinner than the support  with walls, a fluid particle closer than `cutoff` to the edge of
                                    the box in a non-periodic dimension (the wall layers, which lie
                                    inside the box, do not cover its support: layers * dx < cutoff)
    """
    where = f"scene {scene.name}"
    dx = scene.dx
    support = (f"the kernel support (cutoff = {cutoff:g} = {cutoff / dx:g} dx with numerics.kernel "
               f"{numerics.kernel!r}, h_factor {numerics.h_factor:g})")
    box = np.asarray(scene.domain.box, float)
    for d, (side, per) in enumerate(zip(box, scene.domain.periodic)):
        if per and side < 2 * cutoff * (1 - 1e-9):
            raise ConfigError(
                f"{where}: dx = {dx:g} is too coarse: the periodic side {d} of length {side:g} is shorter than twice "
                f"{support}, so a particle would interact with its own periodic image; use dx <= "
                f"{side / (2 * cutoff / dx):.4g} (at least {math.ceil(2 * cutoff / dx)} particles across)")
    fluid = scene.r[scene.fluid_mask]
    if scene.effects.walls is not None:
        for d in range(scene.dim):
            if scene.domain.periodic[d]:
                continue
            if box[d] < 3 * cutoff * (1 - 1e-9):
                raise ConfigError(
                    f"{where}: dx = {dx:g} is too coarse: the walled box is {box[d]:g} wide in dimension {d}, less "
                    f"than two wall layers of {support} plus one support of fluid between them ({3 * cutoff:g}); "
                    f"the fluid cannot be resolved: use dx <= {dx * box[d] / (3 * cutoff):.4g}")
            gap = np.minimum(fluid[:, d], box[d] - fluid[:, d])
            i = int(np.argmin(gap))
            if gap[i] < cutoff * (1 - 1e-6):
                layers = int(round((gap[i] - 0.5 * dx) / dx))
                raise ConfigError(
                    f"{where}: the walls are thinner than {support}: fluid particle {int(np.flatnonzero(scene.fluid_mask)[i])} "
                    f"at {fluid[i].tolist()} is {gap[i]:.4g} from the edge of the box in dimension {d}, so its support "
                    f"reaches beyond the wall layers (about {max(layers, 0)} layers of dx; need layers * dx >= cutoff, "
                    f"i.e. at least {math.ceil(cutoff / dx - 1e-9)} wall layers)")


@dataclass(frozen=True, eq=False)
class Solver:
    """Everything derived from (scene, numerics): constants, neighbour search and the two functions.

    init_fn() -> (state, nbrs)
    step_fn(state, nbrs, step) -> (state, nbrs)     `step` is the number of the step being taken;
                                                    carries `step_fn.guard` (= `guard`)
    state_at(r, u, nbrs) -> state                   traceable: the state init_fn builds at positions
                                                    `r`, velocities `u`, with a given neighbour list
    pairs_fn(r, nbrs) -> Pairs                      the pair geometry the step uses
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
    c_ref: float = float("nan")
    guard: StepGuard = None
    memory_estimate: int = 0

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
    force = scene.body_force
    if fx.gravity is not None:
        if len(fx.gravity) != dim:
            raise ConfigError(f"effects.gravity: has {len(fx.gravity)} components but the scene is {dim}D")
        force = ConstantForce(tuple(float(g) for g in fx.gravity))
    g_max = force.g_max if force is not None else 0.0
    diffusivity = mat.kappa / (mat.rho_ref * mat.c_p) if fx.heat else 0.0
    limits = time_step(h, c_ref, mat.u_ref, mat.eta, mat.rho_ref, g_max, numerics.cfl, diffusivity)
    dt = numerics.dt if numerics.dt is not None else limits["dt"]
    skin = numerics.skin_factor * scene.dx
    check_resolution(scene, kernel.cutoff, skin, numerics)
    memory = check_memory(scene.n, dim, neighbour_slots(kernel.cutoff, skin, scene.dx, dim, numerics.capacity_multiplier),
                          jnp.dtype(dtype).itemsize, f"scene {scene.name}", scene.dx)
    if numerics.dt is not None:
        over = {k: v for k, v in limits.items() if k != "dt" and dt > v * (1 + 1e-9)}
        if over:
            k = max(over, key=lambda name: dt / over[name])
            warnings.warn(
                f"scene {scene.name}: numerics.dt = {dt:.4g} exceeds the {k} time-step limit {over[k]:.4g} by "
                f"{dt / over[k]:.3g}x (limits: " + ", ".join(f"{n} {v:.3g}" for n, v in limits.items() if n != "dt")
                + "); the run is likely to blow up (it is stopped at the first bad step): lower numerics.dt or "
                "set it to null", UnstableTimeStep, stacklevel=2)
    nsearch = make_neighbor_search(scene.domain, kernel.cutoff, skin, numerics.capacity_multiplier,
                                   backend=numerics.neighbor_search)
    margin = kernel.cutoff + skin
    w0 = float(kernel.w(0.0))
    # float32 only: there 1 / sum^2 of a kernel-tail weight sum overflows (walls.fluid_weights);
    # float64 keeps the exact derivative, which the gradient check needs
    weight_floor = walls.WEIGHT_FLOOR * w0 if jnp.dtype(dtype) == jnp.float32 else 0.0
    eta = mat.eta
    reinit = fx.density_reinit_every
    has_walls = fx.walls is not None
    fluid_np, wall_np = scene.fluid_mask, scene.wall_mask
    normal_np = scene.normal if scene.normal is not None else np.zeros_like(scene.r)
    t_fixed_np = scene.T_fixed if scene.T_fixed is not None else np.zeros(scene.n, bool)

    def pairs_of(r, nbrs):
        return pair_geometry(r, nbrs.idx, scene.domain, margin, kernel)

    def evolve_density(pairs, rho, p, u, mass, wall_pairs):
        if fx.riemann:
            drhodt = riemann.continuity(pairs, rho, p, u, mass, c_ref, walls=wall_pairs, rho_of_p=eos.rho)
        else:
            drhodt = density.continuity(pairs, rho, mass, u)
        return rho + dt * drhodt

    def body_force_at(r):
        return force(r) if force is not None else jnp.zeros_like(r)

    def riemann_walls(pairs, r, rho):
        if not (has_walls and fx.riemann):
            return None
        return riemann.wall_pairs(pairs, jnp.asarray(wall_np), jnp.asarray(normal_np, dtype), rho, body_force_at(r))

    def boundary(pairs, r, rho, p, u, v, T):
        """Generalized wall condition: wall p, rho, viscous velocity u~ (and T) from the fluid.
        Returns rho, p, u_visc (u with u~ on walls), v_stress (v with u~ on walls, so A_w = 0), T."""
        if not has_walls:
            return rho, p, u, v, T
        wall = jnp.asarray(wall_np)
        fw = walls.fluid_weights(pairs, jnp.asarray(fluid_np, dtype), weight_floor)
        p = jnp.where(wall, walls.pressure(pairs, fw, p, rho, body_force_at(r)), p)
        rho = jnp.where(wall, eos.rho(p), rho)
        u_hat = walls.extrapolate_vec(pairs, fw, u)
        normal = jnp.asarray(normal_np, dtype) if fx.walls == "free_slip" else None
        u_visc = jnp.where(wall[:, None], walls.velocity(u_hat, u, normal), u)
        v_stress = jnp.where(wall[:, None], u_visc, v)
        if T is not None:
            T = jnp.where(wall & ~jnp.asarray(t_fixed_np), walls.extrapolate(pairs, fw, T), T)
        return rho, p, u_visc, v_stress, T

    def accelerations(pairs, r, rho, p, u, u_visc, v_stress, mass, wall_pairs):
        if fx.riemann:
            dudt = riemann.acceleration(pairs, rho, p, u, mass, eta, c_ref, numerics.eta_limiter,
                                        u_visc=u_visc if has_walls else None, walls=wall_pairs,
                                        rho_of_p=eos.rho)
        else:
            dudt = momentum.acceleration(pairs, rho, p, u_visc, v_stress, mass, eta, fx.tvf)
        if force is not None:
            dudt = dudt + force(r)
        if fx.artificial_viscosity:
            dudt = dudt + momentum.artificial_viscosity(pairs, rho, u_visc, mass, fx.artificial_viscosity, h, c_ref)
        if fx.tvf:
            dvdt = momentum.background_acceleration(pairs, rho, mass, p_b)
        else:
            dvdt = jnp.zeros_like(dudt)
        if has_walls:
            fluid = jnp.asarray(fluid_np)[:, None]
            dudt, dvdt = jnp.where(fluid, dudt, 0.0), jnp.where(fluid, dvdt, 0.0)
        return dudt, dvdt

    def heat_update(pairs, r, rho, T, mass):
        free = jnp.asarray(fluid_np & ~t_fixed_np)
        rate = heat.temperature_rate(pairs, rho, T, mass, mat.kappa, mat.c_p)
        for zone in scene.T_zones:
            if zone.T is None:
                rate = jnp.where(zone.inside(r), 0.0, rate)
        T = T + dt * jnp.where(free, rate, 0.0)
        for zone in scene.T_zones:
            if zone.T is not None:
                T = jnp.where(free & zone.inside(r), zone.T, T)
        return T

    # The pair work of a step is written over the whole list (`pairs`, (N, K) per quantity) and run
    # through `blocked`: functions of the neighbour list idx (first argument) and per-particle fields,
    # evaluated in cache-sized blocks of particles (sph.pairs.row_blocked: the same operations per
    # particle, results equal to round-off, 3-5x faster in 3D than over the whole list at once).
    def geometry(idx, r):
        return pair_geometry(r, idx, scene.domain, margin, kernel)

    def density_of(pairs, r, rho, p, u, mass):
        """rho at r: summation, or rho + dt Drho/Dt (continuity / Riemann) from the state (rho, p, u)."""
        if fx.density_evolution:
            return evolve_density(pairs, rho, p, u, mass, riemann_walls(pairs, r, rho))
        return density.summation(pairs, mass, w0)

    def forces_of(pairs, r, rho, u, v, mass, T, update_heat):
        """Walls, accelerations (and the temperature step): rho, p, dudt, dvdt, T."""
        rho, p, u_visc, v_stress, T = boundary(pairs, r, rho, eos.p(rho), u, v, T)
        dudt, dvdt = accelerations(pairs, r, rho, p, u, u_visc, v_stress, mass, riemann_walls(pairs, r, rho))
        if update_heat:
            T = heat_update(pairs, r, rho, T, mass)
        return rho, p, dudt, dvdt, T

    def blocked(fn, nbrs):
        """fn(nbrs.idx, *args), evaluated in blocks of particles."""
        def call(*args):
            rows = max(1, pairs_module.BLOCK_PAIRS // max(int(nbrs.idx.shape[1]), 1))
            return pairs_module.row_blocked(fn, rows)(nbrs.idx, *args)
        return call

    def state_at(r, u, nbrs):
        n = r.shape[0]
        mass = jnp.full((n,), mat.rho_ref * scene.dx**dim, dtype)
        T = jnp.asarray(np.nan_to_num(scene.T), dtype) if fx.heat else None
        v = jnp.where(jnp.asarray(fluid_np)[:, None], u, 0.0) if has_walls else u

        def fields(idx, r, u, v, mass, T):
            pairs = geometry(idx, r)
            if fx.density_evolution:
                rho = jnp.full((n,), mat.rho_ref, dtype)
            else:
                rho = density.summation(pairs, mass, w0)
            return forces_of(pairs, r, rho, u, v, mass, T, False)

        rho, p, dudt, dvdt, T = blocked(fields, nbrs)(r, u, v, mass, T)
        return ParticleState(r=r, u=u, v=v, rho=rho, p=p, mass=mass,
                             tag=jnp.asarray(scene.tag, jnp.int32), dudt=dudt, dvdt=dvdt, T=T)

    def init_fn():
        r = jnp.asarray(scene.r, dtype)
        nbrs = nsearch.allocate(r)
        # jitted: op-by-op dispatch of the first state costs ~10x its compilation (29 s vs 3 s, ldc dx 0.02)
        return jax.jit(state_at)(r, jnp.asarray(scene.u, dtype), nbrs), nbrs

    def step_fn(state: ParticleState, nbrs, step):
        u = state.u + dt * state.dudt
        v = u + (0.5 * dt) * state.dvdt if fx.tvf else u
        if has_walls:
            v = jnp.where(jnp.asarray(fluid_np)[:, None], v, 0.0)  # walls keep their positions
        r = scene.domain.shift(state.r, dt * v)
        nbrs = nsearch.update(r, nbrs)
        if reinit:  # the re-initialization is a cond between two blocked passes
            rho = blocked(lambda idx, r, *a: density_of(geometry(idx, r), r, *a), nbrs)(
                r, state.rho, state.p, u, state.mass)
            rho = jax.lax.cond(step % reinit == 0,
                               lambda x: blocked(lambda idx, r, x, m: density.reinitialize(geometry(idx, r), x, m, w0),
                                                 nbrs)(r, x, state.mass),
                               lambda x: x, rho)
            rho, p, dudt, dvdt, T = blocked(lambda idx, r, *a: forces_of(geometry(idx, r), r, *a, fx.heat), nbrs)(
                r, rho, u, v, state.mass, state.T)
        else:
            def fields(idx, r, rho, p, u, v, mass, T):
                pairs = geometry(idx, r)
                rho = density_of(pairs, r, rho, p, u, mass)
                return forces_of(pairs, r, rho, u, v, mass, T, fx.heat)

            rho, p, dudt, dvdt, T = blocked(fields, nbrs)(r, state.rho, state.p, u, v, state.mass, state.T)
        return state.replace(r=r, u=u, v=v, rho=rho, p=p, dudt=dudt, dvdt=dvdt, T=T), nbrs

    guard = StepGuard(box=tuple(float(b) for b in scene.domain.box), periodic=tuple(bool(p) for p in scene.domain.periodic),
                      u_limit=float(c_ref), c_ref=float(c_ref), dt=float(dt), dt_limits=dict(limits),
                      fixed_dt=numerics.dt is not None, step_fn=step_fn)
    step_fn.guard = guard
    return Solver(scene=scene, numerics=numerics, kernel=kernel, eos=eos, dt=float(dt), dt_limits=limits,
                  p_b=p_b, dtype=dtype, neighbors=nsearch, init_fn=init_fn, step_fn=step_fn, state_at=state_at,
                  pairs_fn=pairs_of, c_ref=float(c_ref), guard=guard, memory_estimate=memory)
