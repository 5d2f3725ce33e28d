"""`sph.simulate.run`'s chunks on D devices: the sharded layout lives between the frames (issue 40).

    chunks = ShardedChunks(solver, devices=2, chunk_length=write_every)
    chunks.start(state)                       # lay the global state out on the slabs, compile (timed)
    state, reallocations = chunks.advance(step, n)   # n steps; the global state in scene order

The run driver keeps its single-device bookkeeping (frames, writer, checkpoint, diagnostics, blow-up
location) and hands only the advance to the devices: the shards and their capacities stay on the
devices from one chunk to the next, and each frame gathers the global state (`ShardedSolver.collect`,
scene order) for the frame's diagnostics and the writer. The particle order of `sph.reorder` does not
apply (each device's rows are its own); a re-allocation's compilation counts in the wall time.
"""
import time

import jax
import jax.numpy as jnp

from .driver import build_sharded


class ShardedChunks:
    """Advance a solver's global state on `devices` devices (`sph.parallel.build_sharded`), chunk by chunk."""

    def __init__(self, solver, devices: int, chunk_length: int, processes=None):
        # the sharded chunk scans `chunk_length` steps whatever it is asked for (the rest masked): the frame interval
        self.sharded = build_sharded(solver, devices, processes=processes, chunk_length=chunk_length)
        self.shard = self.caps = None
        self.compile_s = 0.0

    @property
    def devices(self) -> int:
        return self.sharded.devices

    def describe(self) -> dict:
        """The decomposition as a run record states it."""
        d = self.sharded.decomp
        return {"devices": d.devices, "processes": jax.process_count(), "axis": int(d.axis),
                "slab_width": float(d.width), "halo_width": float(d.halo), "periodic_axis": bool(d.periodic),
                "platform": jax.devices()[0].platform}

    def start(self, state):
        """Lay `state` (global, scene order) out on the slabs and compile the chunk for its capacities."""
        self.shard, self.caps = self.sharded.distribute(state)
        t0 = time.perf_counter()
        self.sharded.chunk(self.caps).lower(self.shard, 0, 1).compile()
        self.compile_s += time.perf_counter() - t0

    def advance(self, step: int, n: int):
        """(the global state after `n` more steps from global step `step`, in scene order as jax
        arrays; the re-allocations it took). `SlabSkipped` / `HaloOverflow` propagate."""
        self.shard, self.caps, reallocs = self.sharded.advance(self.shard, self.caps, step, n)
        state = jax.tree_util.tree_map(jnp.asarray, self.sharded.collect(self.shard))
        return state, reallocs
