"""What a device holds: its owned particles in fixed-capacity rows (`Shard`), and the host-side
moves between one global `ParticleState` and the D shards (`distribute`, `collect`).

A shard has `capacity` rows; the rows with `valid` hold particles (first, in any order), the rest
are padding with finite values (`fill_row`: positions at the origin, rho_ref, a positive mass, no
velocity), so that a pass evaluated on a padding row (which has no neighbour and is nobody's) gives
finite values and contributes no NaN to a gradient. Every particle carries its id (its row in the
scene, `pid`) and the per-particle constants of the scene that a pass reads through the step's
`Context` (wall normal, Dirichlet-temperature flag, phase), so that they move with it.

Globally a shard's leaves are arrays of D * capacity rows, sharded by blocks over the devices
(`jax.sharding.PartitionSpec(axis)`); inside `shard_map` each device sees its own `capacity` rows.
"""
import math
from dataclasses import dataclass, fields

import jax
import jax.numpy as jnp
import numpy as np

from ..errors import ConfigError
from ..state import FLUID, ParticleState


@dataclass(frozen=True)
class Capacities:
    """Fixed buffer sizes of the sharded step, per device (all static, all >= 1):

    owned     rows of owned particles
    halo      halo rows received from each side
    migrate   particles that may leave to each side in one step
    cells     particle slots per cell of the neighbour search (sph.cell_list's C)
    slots     neighbour slots per particle (K)
    """

    owned: int
    halo: int
    migrate: int
    cells: int
    slots: int

    NAMES = ("owned", "halo", "migrate", "cells", "slots")

    def __post_init__(self):
        for name in self.NAMES:
            v = getattr(self, name)
            if not (isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v >= 1):
                raise ConfigError(f"capacities.{name}: must be a whole number >= 1, got {v!r}")

    def grown(self, overflowed, factor: float = 1.5) -> "Capacities":
        """These capacities with every buffer in `overflowed` (names) `factor` times larger (+1)."""
        return Capacities(**{n: int(math.ceil(getattr(self, n) * factor)) + 1 if n in overflowed else getattr(self, n)
                             for n in self.NAMES})

    def at_least(self, other: "Capacities") -> "Capacities":
        return Capacities(**{n: max(getattr(self, n), getattr(other, n)) for n in self.NAMES})


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Shard:
    """The owned particles of a device (module docstring).

    state    ParticleState of `capacity` rows
    valid    (capacity,) bool, the rows holding a particle
    pid      (capacity,) int32 particle id (row of the scene); -1 on padding
    normal   (capacity, dim) wall normal (zeros without)
    T_fixed  (capacity,) bool, Dirichlet temperature
    phase    (capacity,) int32 phase
    """

    state: ParticleState
    valid: jax.Array
    pid: jax.Array
    normal: jax.Array
    T_fixed: jax.Array
    phase: jax.Array

    @property
    def capacity(self) -> int:
        return self.valid.shape[0]


def fill_row(scene, dtype) -> Shard:
    """One padding row (shape (1, ...)): finite values on which every pass stays finite."""
    dim = scene.dim
    z = np.zeros((1, dim), dtype)
    m = float(np.median(scene.particle_mass))
    state = ParticleState(r=z, u=z, v=z, rho=np.full(1, scene.material.rho_ref, dtype), p=np.zeros(1, dtype),
                          mass=np.full(1, m, dtype), tag=np.full(1, FLUID, np.int32), dudt=z, dvdt=z,
                          T=np.zeros(1, dtype) if scene.effects.heat else None)
    return Shard(state=state, valid=np.zeros(1, bool), pid=np.full(1, -1, np.int32), normal=z,
                 T_fixed=np.zeros(1, bool), phase=np.zeros(1, np.int32))


def particle_constants(scene, dtype):
    """(normal, T_fixed, phase) of every particle of the scene, in scene order."""
    normal = scene.normal if scene.normal is not None else np.zeros_like(scene.r)
    t_fixed = scene.T_fixed if scene.T_fixed is not None else np.zeros(scene.n, bool)
    return np.asarray(normal, dtype), np.asarray(t_fixed, bool), np.asarray(scene.phases, np.int32)


def owners(decomp, r) -> np.ndarray:
    """(N,) the slab owning each position (host side)."""
    return np.asarray(decomp.slab_of(np.asarray(r)[:, decomp.axis]))


def distribute(state: ParticleState, scene, decomp, capacity: int) -> Shard:
    """The global state (scene order) as D shards of `capacity` rows each, stacked (D * capacity
    rows, numpy): each particle goes to the slab of its position. Refuses a slab holding more
    particles than `capacity` (the caller sizes it, `sizes`)."""
    dtype = np.asarray(state.r).dtype
    own = owners(decomp, state.r)
    normal, t_fixed, phase = particle_constants(scene, dtype)
    fill = fill_row(scene, dtype)
    host = {f.name: np.asarray(getattr(state, f.name)) for f in fields(ParticleState)
            if getattr(state, f.name) is not None}
    blocks = []
    for k in range(decomp.devices):
        ids = np.flatnonzero(own == k)
        if len(ids) > capacity:
            raise ConfigError(f"capacities.owned: slab {k} holds {len(ids)} particles, more than {capacity}")
        pad = capacity - len(ids)

        def rows(x, f):
            return np.concatenate([x[ids], np.repeat(f, pad, axis=0)])

        st = ParticleState(**{n: rows(x, getattr(fill.state, n)) for n, x in host.items()})
        blocks.append(Shard(state=st, valid=rows(np.ones(scene.n, bool), fill.valid),
                            pid=rows(np.arange(scene.n, dtype=np.int32), fill.pid), normal=rows(normal, fill.normal),
                            T_fixed=rows(t_fixed, fill.T_fixed), phase=rows(phase, fill.phase)))
    return jax.tree_util.tree_map(lambda *xs: np.concatenate(xs), *blocks)


def collect(shard: Shard, n: int) -> ParticleState:
    """The global state in scene order (numpy) from stacked shards; refuses a particle missing or
    held twice (never silently)."""
    valid = np.asarray(shard.valid)
    pid = np.asarray(shard.pid)[valid]
    if len(pid) != n or not np.array_equal(np.sort(pid), np.arange(n)):
        missing = np.setdiff1d(np.arange(n), pid)
        twice = np.flatnonzero(np.bincount(pid, minlength=n) > 1)
        raise RuntimeError(f"sharded state: {len(pid)} particles held for {n}; missing ids {missing[:5].tolist()}, "
                           f"held twice {twice[:5].tolist()}")
    order = np.argsort(pid)

    def back(x):
        return None if x is None else np.asarray(x)[valid][order]

    st = shard.state
    return ParticleState(**{f.name: back(getattr(st, f.name)) for f in fields(ParticleState)})


def slab_counts(decomp, r) -> np.ndarray:
    """(D,) particles each slab owns at positions r."""
    return np.bincount(owners(decomp, r), minlength=decomp.devices)


def halo_counts(decomp, r) -> np.ndarray:
    """(D, 2) halo particles each device receives from its lower and upper neighbour at positions r
    (those within the halo width of its faces, measured across the periodic wrap)."""
    x = np.asarray(r)[:, decomp.axis]
    own = owners(decomp, r)
    out = np.zeros((decomp.devices, 2), int)
    if decomp.devices == 1:
        return out
    w = decomp.width
    lo = own * w
    to_lower = (x - lo) < decomp.halo          # sent to slab k - 1 (its upper halo)
    to_upper = ((own + 1) * w - x) < decomp.halo
    for k in range(decomp.devices):
        for src, shift, send, col in ((k + 1, -1, to_lower, 1), (k - 1, +1, to_upper, 0)):
            if not decomp.periodic and not (0 <= src < decomp.devices):
                continue
            out[k, col] += int(np.sum(send & (own == src % decomp.devices)))
    return out


def as_device_arrays(shard: Shard, sharding) -> Shard:
    """The stacked host shards (every process holds all of them) placed on the devices of `sharding`,
    each device taking its block (`jax.make_array_from_callback`: one process or several)."""
    def put(x):
        x = np.asarray(x)
        return jax.make_array_from_callback(x.shape, sharding, lambda index: jnp.asarray(x[index]))

    return jax.tree_util.tree_map(put, shard)
