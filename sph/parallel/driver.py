"""The sharded step and rollouts: the single-device step's pass list on D devices (issue 40).

    sharded = build_sharded(solver, devices=4)          # solver = sph.build_solver(scene, numerics)
    shard, caps = sharded.distribute(state)             # state: the global ParticleState (init_fn)
    shard, caps, n_realloc = sharded.advance(shard, caps, 0, 200)    # re-allocating on overflow
    state = sharded.collect(shard)                      # global, in scene order (numpy)

One step on every device, under `jax.shard_map` over a 1D mesh of the slabs:
  1. kick and drift of the owned particles                `sph.step.kick_drift` (the same function)
  when some particle of any device has moved more than skin / 2 since the last rebuild (`lax.cond`):
  2. migration to the new owners                          `sph.parallel.migration`
  3. halo lists                                           `sph.parallel.halo.build`
  4. neighbour list of owned + halo particles             `sph.parallel.neighbors` (sph.cell_list)
  then, every step:
  5. the exchange of the fields the passes read before any pass writes them (ExchangePlan.initial)
  6. the scene's passes in order (`solver.passes`, the very objects of the single-device step), each
     preceded by the exchange of the fields it reads that an earlier pass wrote (ExchangePlan.before)
Only the owned rows leave the step. Between rebuilds the owned rows and the halo lists stay (a
particle may be up to skin / 2 outside its slab) and the halo, cutoff + skin wide, holds every
particle that can come within the cutoff of an owned one: the Verlet-list scheme of GROMACS and
LAMMPS. So an owned particle sums over the single device's pairs, in another order: the fields
agree to round-off.

Every buffer has a fixed capacity (`Capacities`) and the step returns how much it needed; a step
that needed more is not taken (the scan keeps the last good state, as `sph.rollout.make_chunk`),
and `advance` re-lays the particles out with larger buffers and redoes it. A particle that crossed
more than one slab in a step is refused (`SlabSkipped`); an overflow that persists after
`max_reallocations` raises `HaloOverflow`. `rollout` is the differentiable counterpart of
`sph.rollout.scan_rollout` (fixed capacities, flags returned).
"""
import math
from dataclasses import dataclass, field, replace
from typing import Optional

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec as P

from ..cell_list import CellNeighborList, make_cell_list
from ..constants import derive
from ..errors import SimulationError
from ..errors import ConfigError
from ..fields import Fields
from ..passes import Context
from ..state import FLUID, MOVING_WALL, WALL, ParticleState
from ..step import kick_drift
from . import halo as halo_mod
from .decomposition import decompose
from .halo import CONSTANTS, ExchangePlan, extend
from .layout import Capacities, Shard, as_device_arrays, collect, distribute, fill_row, halo_counts, slab_counts
from .migration import migrate
from .neighbors import masked_search

AXIS = "slabs"
"""The mesh axis of the slabs."""

FLAGS = ("migrate", "owned", "halo", "list")
"""The overflow flags of a step, in the order `local_step` returns them."""


class SlabSkipped(SimulationError):
    """A particle moved more than one slab in one step."""


class HaloOverflow(SimulationError):
    """A buffer of the sharded step still overflowed after re-allocation."""


@dataclass(frozen=True, eq=False)
class ShardedSolver:
    """The sharded counterpart of a `sph.solver.Solver` (module docstring). `mesh` is the 1D device
    mesh of the slabs, `plan` the exchange plan of the pass list, `ctx` the single-device Context
    (its constants and pair geometry; the per-particle arrays are replaced by the device's rows)."""

    solver: object
    decomp: object
    plan: ExchangePlan
    mesh: Mesh
    ctx: Context
    search: object
    fill: Shard
    chunk_length: int = 100
    compiled: dict = field(default_factory=dict, repr=False)   # (kind, capacities, ...) -> jitted function

    @property
    def devices(self) -> int:
        return self.decomp.devices

    @property
    def sharding(self) -> NamedSharding:
        return NamedSharding(self.mesh, P(AXIS))

    # -- host side ---------------------------------------------------------------------------------

    def capacities(self, state: ParticleState, margin: float = 1.25, list_margin: float = 1.0) -> Capacities:
        """Buffers for the particles at `state.r`: the largest slab times `margin`, the largest halo
        times 1.2 `margin` (its count fluctuates as particles cross the halo's inner edge), a quarter
        of the largest halo as migration buffer, the list's capacities of the whole state (every
        device's rows are a subset of it; `sph.neighbors`' capacity multiplier) times `list_margin`
        (a lattice start, whose cells hold exactly the same count, soon needs more)."""
        r = np.asarray(state.r)
        owned = int(slab_counts(self.decomp, r).max())
        halo = int(halo_counts(self.decomp, r).max())
        nbrs = self.solver.neighbors.allocate(jnp.asarray(r))
        cells = int(getattr(nbrs, "cell_list_capacity", 0) or 0) or int(nbrs.max_occupancy)
        return Capacities(owned=int(math.ceil(owned * margin)) + 8, halo=int(math.ceil(halo * 1.2 * margin)) + 8,
                          migrate=max(16, halo // 4), cells=int(math.ceil(cells * list_margin)),
                          slots=int(math.ceil(nbrs.max_occupancy * list_margin)))

    def distribute(self, state: ParticleState, caps: Capacities = None):
        """(the global state laid out on the devices, its capacities)."""
        caps = caps or self.capacities(state)
        host = distribute(state, self.solver.scene, self.decomp, caps.owned)
        return as_device_arrays(host, self.sharding), caps

    def collect(self, shard: Shard) -> ParticleState:
        """The global state in scene order (numpy), from every process's devices."""
        return collect(gather(shard), self.solver.scene.n)

    # -- the step on one device --------------------------------------------------------------------

    def empty_cache(self, caps: Capacities) -> "Cache":
        """A cache that makes the next step rebuild (halo lists and neighbour list of the right shapes)."""
        d, m, h = self.devices, caps.owned, caps.halo
        rows = m + 2 * h if d > 1 else m
        zi, zb = jnp.zeros(h, jnp.int32), jnp.zeros(h, bool)
        halo = halo_mod.Halo(zi, zi, zb, zb, zb, zb) if d > 1 else None
        nbrs = CellNeighborList(idx=jnp.full((rows, caps.slots), rows, jnp.int32),
                                reference_position=jnp.zeros((rows, self.solver.scene.dim), self.ctx.c.dtype),
                                did_buffer_overflow=jnp.zeros((), bool), max_occupancy=caps.slots,
                                cell_list_capacity=caps.cells)
        return Cache(halo=halo, nbrs=nbrs, built=jnp.zeros((), bool))

    def local_step(self, sh: Shard, cache: "Cache", step, caps: Capacities):
        """One step on this device's rows: (shard, cache, needs, far). needs (4,) int, the largest
        over the devices of: particles sent to one side, owned rows, halo rows from one side (the
        buffers `migrate`, `owned`, `halo`), and 1 if the neighbour list overflowed; far: the
        particles that crossed more than one slab, summed over the devices.

        Steps 2-4 (migration, halo lists, neighbour list) run only when some particle of any device
        has moved more than skin / 2 since they last ran (the Verlet criterion of sph.cell_list, over
        all devices), or when `cache` was never built; between, the owned rows and the halo lists
        stay and only the fields are exchanged (GROMACS' scheme: the halo, cutoff + skin wide, holds
        every particle that can come within the cutoff before the next rebuild)."""
        sc, c, dec = self.solver.scene, self.ctx.c, self.decomp
        walls = sc.effects.walls is not None
        fluid = (sh.state.tag == FLUID) if walls else None
        sh = replace(sh, state=kick_drift(Fields.of(sh.state), c.dt, sc.effects.tvf, fluid, sc.domain).state())  # 1.
        m, zero, many = caps.owned, jnp.zeros((), jnp.int32), dec.devices > 1
        # a drift longer than a slab (on a periodic axis a slab index alone cannot tell: 2.5 slabs up is 1.5 down)
        leap = jnp.sum(sh.valid & (jnp.abs(c.dt * sh.state.v[:, dec.axis]) > dec.width), dtype=jnp.int32)
        h = caps.halo if many else 0
        moved = self._moved(sh, cache)
        if many:
            moved = jax.lax.pmax(moved.astype(jnp.int32), AXIS) > 0

        def rebuild(sh):
            if many:
                sh, (n_send, n_own), far = migrate(dec, AXIS, sh, self.fill, caps.migrate)                 # 2.
                halo, n_halo = halo_mod.build(dec, AXIS, sh.state.r, sh.valid, caps.halo)                   # 3.
                r = halo_mod.exchange(dec, AXIS, halo, {"r": extend(sh.state.r, self.fill.state.r, h)}, m)["r"]
                valid = jnp.concatenate([sh.valid, halo.from_down, halo.from_up])
            else:
                n_send, n_own, far, n_halo, halo, r, valid = zero, zero, zero, zero, None, sh.state.r, sh.valid
            nbrs = self.search.build(r, valid, caps.cells, caps.slots)                                      # 4.
            needs = jnp.stack([n_send, n_own, n_halo, nbrs.did_buffer_overflow.astype(jnp.int32)]).astype(jnp.int32)
            return sh, Cache(halo=halo, nbrs=nbrs, built=jnp.ones((), bool)), needs, far

        def reuse(sh):
            return sh, cache, jnp.zeros(len(FLAGS), jnp.int32), zero

        sh, cache, needs, far = jax.lax.cond(moved | ~cache.built, rebuild, reuse, sh)
        far = far + leap if many else zero
        fill, halo = self.fill, cache.halo
        arrays = {n: extend(x, getattr(fill.state, n), h) for n, x in vars(sh.state).items() if x is not None}
        consts = {n: extend(getattr(sh, n), getattr(fill, n), h) for n in CONSTANTS + ("T_fixed",)}
        if many:
            got = halo_mod.exchange(dec, AXIS, halo, {n: {**arrays, **consts}[n] for n in self.plan.initial}, m)
            arrays.update({n: x for n, x in got.items() if n in arrays})
            consts.update({n: x for n, x in got.items() if n in consts})
        f = Fields(**arrays)
        ctx = replace(self.ctx, fluid=f.tag == FLUID, wall=(f.tag == WALL) | (f.tag == MOVING_WALL),
                      normal=consts["normal"], T_fixed=consts["T_fixed"], phase=consts["phase"])
        for p, send in zip(self.solver.passes, self.plan.before):                                            # 5.
            if send and many:
                f = f.replace(**halo_mod.exchange(dec, AXIS, halo, {n: getattr(f, n) for n in send}, m))
            f = p(f, ctx, cache.nbrs.idx, step)
        out = replace(sh, state=jax.tree_util.tree_map(lambda x: x[:m], f.state()))
        if many:
            needs, far = jax.lax.pmax(needs, AXIS), jax.lax.psum(far, AXIS)
        return out, cache, needs, far

    def _moved(self, sh: Shard, cache: "Cache"):
        """Whether an owned particle moved more than skin / 2 (minimum image) since the list was built."""
        r = jax.lax.stop_gradient(sh.state.r)
        ref = cache.nbrs.reference_position[:r.shape[0]]
        d2 = 0.0
        for a in range(r.shape[1]):
            d2 = d2 + self.search._minimum_image(r[:, a] - ref[:, a], a) ** 2
        return jnp.max(jnp.where(sh.valid, d2, 0.0)) > (0.5 * self.search.skin) ** 2

    # -- jitted rollouts ---------------------------------------------------------------------------

    def _map(self, local, n_replicated: int, n_out: int):
        return jax.jit(jax.shard_map(local, mesh=self.mesh, in_specs=(P(AXIS),) + (P(),) * n_replicated,
                                     out_specs=(P(AXIS),) * n_out, check_vma=False))

    def chunk(self, caps: Capacities):
        """chunk(shard, step0, n_target) -> (shard, n_done (D,), needs (D, 4), far (D,)): up to
        `chunk_length` steps, stopping (the last good state kept) at a step that overflows or is refused."""
        return _chunk(self, caps)

    def rollout(self, caps: Capacities, n_steps: int):
        """rollout(shard, step0) -> (shard, needs (D, 4), far (D,)): `n_steps` steps with `lax.scan`,
        differentiable; the result is valid only if no need overflows `caps` (`overflows`) and far is 0."""
        return _rollout(self, caps, n_steps)

    def advance(self, shard: Shard, caps: Capacities, step0: int, n: int, max_reallocations: int = 5):
        """Advance exactly `n` steps from global step `step0`, re-allocating larger buffers (and
        redoing the step) on overflow. Returns (shard, caps, reallocations)."""
        done, reallocs = 0, 0
        while done < n:
            shard, n_done, needs, far = self.chunk(caps)(shard, step0 + done, n - done)
            done += int(np.asarray(gather(n_done))[0])
            needs, far = np.asarray(gather(needs)).reshape(-1, len(FLAGS))[0], int(np.asarray(gather(far))[0])
            over = np.asarray(overflows(needs, caps))
            if far:
                raise SlabSkipped(f"sharded step {step0 + done + 1}: {far} particle(s) moved more than one slab "
                                  f"(width {self.decomp.width:g}) in one step; the time step is too large for "
                                  f"{self.devices} slabs", step=step0 + done + 1)
            if over.any():
                names = [n for n, bad in zip(FLAGS, over) if bad]
                reallocs += 1
                if reallocs > max_reallocations:
                    raise HaloOverflow(f"sharded step {step0 + done + 1}: buffers {names} still overflow after "
                                       f"{max_reallocations} re-allocations (capacities {caps})", step=step0 + done + 1)
                shard, caps = self.distribute(self.collect(shard), grown(caps, needs))
        return shard, caps, reallocs


def _chunk(s: ShardedSolver, caps: Capacities):
    key = ("chunk", caps)
    if key in s.compiled:
        return s.compiled[key]

    def local(sh, step0, n_target):
        def body(carry, _):
            sh, cache, n_done, needs, far = carry
            active = (n_done < n_target) & ~jnp.any(overflows(needs, caps)) & (far == 0)
            new, new_cache, nd, fr = s.local_step(sh, cache, step0 + n_done + 1, caps)
            take = active & ~(jnp.any(overflows(nd, caps)) | (fr > 0))
            sh, cache = jax.tree_util.tree_map(lambda a, b: jnp.where(take, a, b), (new, new_cache), (sh, cache))
            return (sh, cache, n_done + take.astype(jnp.int32), jnp.where(active, jnp.maximum(needs, nd), needs),
                    far + jnp.where(active, fr, 0)), None

        init = (sh, s.empty_cache(caps), jnp.zeros((), jnp.int32), jnp.zeros(len(FLAGS), jnp.int32),
                jnp.zeros((), jnp.int32))
        (sh, _, n_done, needs, far), _ = jax.lax.scan(body, init, None, length=s.chunk_length)
        return sh, n_done[None], needs[None], far[None]

    s.compiled[key] = fn = s._map(local, 2, 4)
    return fn


def _rollout(s: ShardedSolver, caps: Capacities, n_steps: int):
    key = ("rollout", caps, n_steps)
    if key in s.compiled:
        return s.compiled[key]

    def local(sh, step0):
        def body(carry, k):
            sh, cache, needs, far = carry
            sh, cache, nd, fr = s.local_step(sh, cache, step0 + k + 1, caps)
            return (sh, cache, jnp.maximum(needs, nd), far + fr), None

        init = (sh, s.empty_cache(caps), jnp.zeros(len(FLAGS), jnp.int32), jnp.zeros((), jnp.int32))
        (sh, _, needs, far), _ = jax.lax.scan(body, init, jnp.arange(n_steps))
        return sh, needs[None], far[None]

    s.compiled[key] = fn = s._map(local, 1, 3)
    return fn


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Cache:
    """What a step leaves the next one on a device: the halo lists, the neighbour list of owned +
    halo rows, and whether they were ever built (a chunk starts with an unbuilt cache)."""

    halo: Optional[halo_mod.Halo]
    nbrs: CellNeighborList
    built: jax.Array


def overflows(needs, caps: Capacities):
    """(4,) bool: which of the FLAGS' buffers `needs` (`ShardedSolver.local_step`) exceed `caps`."""
    cap = jnp.asarray([caps.migrate, caps.owned, caps.halo, 0], jnp.int32)
    return needs > cap


def grown(caps: Capacities, needs) -> Capacities:
    """`caps` with every overflowed buffer grown to 1.25 x what was needed (and at least 1.5 x): the
    counts of `needs`; an overflowed list grows its cell and neighbour slots."""
    over = np.asarray(needs) > np.array([caps.migrate, caps.owned, caps.halo, 0])
    names = {n for n, o in zip(FLAGS, over) if o}
    out = caps.grown(names | ({"cells", "slots"} if "list" in names else set()))
    need = {n: int(math.ceil(1.25 * v)) for n, v, o in zip(FLAGS, np.asarray(needs), over) if o and n != "list"}
    return out.at_least(replace(out, **need)) if need else out


def gather(tree):
    """A pytree of global arrays as host numpy arrays, from every process (one process: plain copy)."""
    def one(x):
        if isinstance(x, jax.Array) and not x.is_fully_addressable:
            from jax.experimental import multihost_utils

            return np.asarray(multihost_utils.process_allgather(x, tiled=True))
        return np.asarray(x)

    return jax.tree_util.tree_map(one, tree)


def build_sharded(solver, devices: int, axis=None, device_list=None, chunk_length: int = 100,
                  processes: int = None) -> ShardedSolver:
    """The sharded solver of `solver` (sph.build_solver) on `devices` devices (the first of
    `device_list`, default `jax.devices()`, every process's), slabs along `axis` (default the longest).
    `processes`: the process count the run was configured for; refused if the launch started another."""
    if processes is not None and processes != jax.process_count():
        raise ConfigError(f"processes: the run is configured for {processes} process(es) but {jax.process_count()} "
                          f"were launched (jax.distributed.initialize(num_processes=...)); launch {processes} or "
                          f"configure {jax.process_count()}")
    sc, numerics = solver.scene, solver.numerics
    c = derive(sc, numerics)
    decomp = decompose(sc.domain, c.margin, devices, axis)
    available = list(device_list if device_list is not None else jax.devices())
    if devices > len(available):
        raise ValueError(f"devices: {devices} asked for but {len(available)} available (on CPU, set XLA_FLAGS="
                         f"--xla_force_host_platform_device_count={devices} before jax is imported)")
    mesh = Mesh(np.array(available[:devices]), (AXIS,))
    search = masked_search(make_cell_list(sc.domain, c.kernel.cutoff, c.skin, numerics.capacity_multiplier))
    return ShardedSolver(solver=solver, decomp=decomp, plan=ExchangePlan.of(solver.passes), mesh=mesh,
                         ctx=Context.of(sc, c), search=search, fill=fill_row(sc, np.dtype(c.dtype)),
                         chunk_length=chunk_length)
