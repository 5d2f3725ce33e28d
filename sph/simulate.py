"""Simulation driver: advance a solver in chunks, record a frame after each, write, resume.

`run(solver, state, nbrs, t_end, write_every, writer)` advances `write_every` steps per jitted chunk
(`sph.rollout.make_chunk` + `advance`, so neighbour-list overflow re-allocates and never loses a
step). After every chunk it records a frame (t, u_max, E_kin, max density error; positions and
kept fields go to the optional writer, `lab.io.TrajectoryWriter`) and overwrites its
checkpoint, so an interrupted run continues with `resume(solver, writer)` + `run(..., step0=step)`.

Timing (`sph.compiled`): the chunk is compiled ahead of every call with new shapes (`jit(...).lower(...).compile()`,
which fills the same cache the calls use, without taking a step): before the loop and again after a
neighbour re-allocation changes the list's capacity. That time is `compile_s`; `wall_s` is the
solve time of the chunks only, each synchronised with `block_until_ready`, compilation excluded.

Every step is guarded (`solver.guard`, `sph.guard.StepGuard`, on by default): a step after
which a fluid particle is outside the domain in a non-periodic dimension (`ParticleEscaped`), a
fluid speed exceeds `u_limit` (default: the artificial sound speed c_ref, a finite blow-up) or a
velocity or density is non-finite (`BlowUp`) is not taken; the neighbour list overflowing again
and again is `NeighborOverflow`. `run` then raises that `SimulationError` (a RuntimeError) naming
the step, the time, the particle, its position and the likely cause (dt against its limits); a bad
state the guard does not see (another field non-finite) is found at the end of the chunk and
located by bisecting the chunk from its last good state (`sph.blowup`). The writer keeps the last good frame and
its checkpoint, and the message says where.

Devices (`devices`, default 1): with D > 1 the chunks run on D devices (`sph.parallel`: slabs,
halo exchange, migration; `sph.parallel.chunks`), equal to one device's to round-off; each frame
gathers the global state, so frames, checkpoints, callbacks and diagnostics are as on one device. A
bad chunk is then located by the single-device bisection from its last good frame. The particle
order below does not apply (each device's rows are its own).

Particle order (`reorder_every`, default numerics.reorder_every; `sph.reorder`): every that many
steps (at the next frame), and before the first chunk of a resumed run (whose checkpoint is in the
scene's order), the fluid particles are sorted by cell among their slots and the neighbour list is
rebuilt, so that the gathers of the pair sums stay local as the flow mixes the
particles. Everything the run hands out (frames, checkpoints, callbacks, the returned state and
list) is in the scene's order; the permuted state lives only between the chunks. A chunk that fails
in a permuted order is retried from its start in the scene's order, so that every diagnosis names
the scene's particle numbers.
"""
import dataclasses
import time
from dataclasses import dataclass
from functools import partial
from typing import Callable, Optional

import jax
import numpy as np
from tqdm.auto import tqdm

from . import diagnostics, reorder
from .blowup import is_bad, locate_blowup, with_checkpoint
from .compiled import CompiledChunk
from .errors import SimulationError
from .rollout import advance, make_chunk
from .state import ParticleState

SERIES = ("time", "step", "u_max", "e_kin", "density_error")
"""The per-frame scalars a run records (simulated time, step, and the frame diagnostics)."""


@dataclass(frozen=True, eq=False)
class RunResult:
    """Frames (all of them, including those written before a resume) and timings.

    wall_s, compile_s, n_steps, n_reallocations count this call only; wall_s_total and
    n_reallocations_total include the earlier sessions of a resumed run (kept in the checkpoint).
    """

    t: np.ndarray
    step: np.ndarray
    u_max: np.ndarray
    e_kin: np.ndarray
    density_error: np.ndarray
    wall_s: float
    compile_s: float
    n_steps: int
    n_reallocations: int
    wall_s_total: float
    n_reallocations_total: int
    step_end: int
    write_every: int
    state: ParticleState
    nbrs: object
    n_reorders: int = 0
    decomposition: Optional[dict] = None
    """With devices > 1: the decomposition (`sph.parallel.chunks.ShardedChunks.describe`)."""

    @property
    def ms_per_step(self) -> float:
        return 1e3 * self.wall_s / self.n_steps if self.n_steps else float("nan")


def resume(solver, writer):
    """(state, nbrs, step) from the checkpoint of `writer`, with a freshly allocated neighbour list."""
    state, step, _ = writer.load_checkpoint()
    return state, solver.neighbors.allocate(state.r), step


def run(solver, state, nbrs, t_end: float, write_every: int, writer=None, progress: bool = True,
        step0: int = 0, *, n_steps: Optional[int] = None, callback: Optional[Callable] = None,
        desc: Optional[str] = None, max_reallocations: int = 10, u_limit: Optional[float] = None,
        reorder_every: Optional[int] = None, devices: int = 1) -> RunResult:
    """Advance from global step `step0` to `n_steps` (default `solver.n_steps(t_end)`) in chunks of
    `write_every` steps (the last one may be shorter), recording a frame after each chunk.

    A fresh run (`step0 == 0`) records the initial frame first. With a `writer`, frames go to the file
    and the checkpoint is overwritten after each frame; resuming (`step0 > 0`) reads the earlier
    frames back from it. `callback(step, t, state)` is called after every frame (raise in it to stop).
    `u_limit`: treat a fluid speed above it as a blow-up; None (default) = the artificial sound
    speed `solver.c_ref` (a WCSPH flow is meaningless long before Ma = 1); math.inf switches the
    speed check off (non-finite fields and particles leaving the domain still stop the run).
    `reorder_every`: sort the particles by cell every that many steps (None: numerics.reorder_every;
    0: never); results equal the unsorted run's to round-off (the pair sums' order changes).
    `devices`: run the chunks on that many devices (module docstring; no sorting then).
    """
    n_total, u_limit, reorder_every = _checked(solver, t_end, write_every, step0, n_steps, u_limit, reorder_every)
    sharded = None
    if devices != 1:
        from .parallel.chunks import ShardedChunks

        sharded, reorder_every = ShardedChunks(solver, devices, max(1, min(write_every, n_total - step0))), 0
    session = _Session(solver, write_every, writer, u_limit, reorder_every, max_reallocations, sharded)
    session.begin(state, nbrs, step0, n_total)
    bar = tqdm(total=n_total, initial=step0, disable=not progress, desc=desc, unit="step",
               mininterval=2.0, dynamic_ncols=True)
    try:
        while session.step < n_total:
            n = min(write_every, n_total - session.step)
            d = session.advance(n)
            if d is None:  # failed in a permuted order: retried from the chunk's start in the scene's order
                continue
            bar.update(n)
            bar.set_postfix(t=f"{session.step * solver.dt:.3g}", u_max=f"{d['u_max']:.4g}", refresh=False)
            if callback is not None:
                callback(session.step, session.step * solver.dt, session.scene_state())
    finally:
        bar.close()
    return session.result(step0)


def states_at(solver, state, nbrs, times, fluid_only: bool = True, chunk: int = 500) -> list:
    """The states at `times` (a list, in the order given), advanced from `state` at t = 0 with the
    solver's step guard (a blow-up raises, naming the step). Each time must be a whole number of
    steps (within 1e-9 dt): another time raises a ValueError naming it and the two nearest ones,
    rather than being skipped. `fluid_only`: the fluid particles' rows only (walls left out)."""
    steps = []
    for t in times:
        k = t / solver.dt
        if not (np.isfinite(k) and k >= -1e-9 and abs(k - round(k)) <= 1e-9 * max(1.0, abs(k))):
            lo = max(0, int(np.floor(k))) if np.isfinite(k) else 0
            raise ValueError(f"times: t = {t!r} is not a whole number of steps dt = {solver.dt:.6g}; the nearest are "
                             f"{lo * solver.dt:.10g} and {(lo + 1) * solver.dt:.10g}")
        steps.append(int(round(k)))
    fluid = np.asarray(solver.scene.fluid_mask)
    jitted = jax.jit(make_chunk(solver.step_fn, chunk, guard=solver.guard))
    done, out = 0, {}
    for k in sorted(set(steps)):
        if k > done:
            state, nbrs, _ = advance(jitted, solver.neighbors, state, nbrs, done, k - done)
            done = k
        out[k] = jax.tree_util.tree_map(lambda x: x[fluid], state) if fluid_only else state
    return [out[k] for k in steps]


def _checked(solver, t_end, write_every, step0, n_steps, u_limit, reorder_every) -> tuple:
    """(n_total, u_limit, reorder_every) of `run`, defaults filled in; a ValueError for a bad one."""
    if write_every < 1:
        raise ValueError(f"write_every must be >= 1, got {write_every}")
    n_total = solver.n_steps(t_end) if n_steps is None else int(n_steps)
    if not 0 <= step0 <= n_total:
        raise ValueError(f"step0={step0} is outside [0, {n_total}]")
    if reorder_every is None:
        reorder_every = solver.numerics.reorder_every
    if reorder_every < 0:
        raise ValueError(f"reorder_every must be >= 0, got {reorder_every}")
    return n_total, solver.c_ref if u_limit is None else u_limit, reorder_every


class _Session:
    """One call of `run`: the jitted chunk, list rebuild and diagnostics; the current state, list
    and step; the frames recorded (with those of earlier sessions); the particle order; the timings."""

    def __init__(self, solver, write_every: int, writer, u_limit: float, reorder_every: int,
                 max_reallocations: int, sharded=None):
        self.solver, self.write_every, self.writer, self.sharded = solver, write_every, writer, sharded
        self.u_limit, self.reorder_every, self.max_reallocations = u_limit, reorder_every, max_reallocations
        guard = solver.guard.with_limit(u_limit) if solver.guard is not None else None
        self.chunk = CompiledChunk(jax.jit(make_chunk(solver.step_fn, write_every, guard=guard)))
        self.movable = reorder.movable_mask(solver.scene) if reorder_every else None
        self.rebuild = CompiledChunk(jax.jit(solver.neighbors.update)) if reorder_every else None
        self.diag_fn = jax.jit(partial(diagnostics.summary, rho_ref=solver.scene.material.rho_ref))
        self.frames = {k: [] for k in SERIES}
        self.wall_prev, self.realloc_prev = 0.0, 0  # of the earlier sessions of a resumed run
        self.wall, self.reallocs, self.n_reorders, self.diag_compile_s = 0.0, 0, 0, 0.0
        self.order, self.since = None, 0  # order[i]: the scene's number of the particle in slot i
        self.state = self.nbrs = None
        self.step = 0

    @property
    def compile_s(self) -> float:
        """Compilation time so far: diagnostics, chunk and list rebuild."""
        rebuild_s = self.rebuild.compile_s if self.rebuild is not None else 0.0
        sharded_s = self.sharded.compile_s if self.sharded is not None else 0.0
        return self.diag_compile_s + self.chunk.compile_s + rebuild_s + sharded_s

    def begin(self, state, nbrs, step0: int, n_total: int):
        """Start at `state` (the scene's order) at global step `step0`: the earlier frames read back,
        the initial state checked and recorded, everything compiled before the first chunk."""
        self.state, self.nbrs, self.step = state, nbrs, step0
        # a resumed state is in the scene's order, not sorted: reorder before the first chunk
        self.since = self.reorder_every if step0 > 0 else 0
        self._read_earlier_frames(step0)
        t0 = time.perf_counter()
        self.diag_fn.lower(state).compile()
        self.diag_compile_s = time.perf_counter() - t0
        d0 = self._diagnostics(state)
        if d0["first_nonfinite"] >= 0:
            i = int(d0["first_nonfinite"])
            raise RuntimeError(f"the state at step {step0} (t={step0 * self.solver.dt:.6g}) is not finite: "
                               f"particle {i} has non-finite {diagnostics.nonfinite_fields(state, i)}")
        if step0 == 0 and (self.writer is None or self.writer.n_frames == 0):
            self.record(state, 0, d0)
        elif not self.frames["step"]:
            self._append_frame(step0, d0)
        # Compile without advancing: lower + compile fills the cache that the calls hit.
        if step0 < n_total and self.sharded is not None:
            self.sharded.start(state)  # the single-device chunk compiles only if a bad chunk is located
        elif step0 < n_total:
            self.chunk.compile(state, nbrs, step0, min(self.write_every, n_total - step0))
            if self.rebuild is not None:
                self.rebuild.compile(state.r, nbrs)

    def _read_earlier_frames(self, step0: int):
        """A resumed run (`step0 > 0`) with a writer: its frames up to step0, and the wall time and
        re-allocations of the earlier sessions where the checkpoint is the one at step0."""
        if self.writer is None or step0 <= 0:
            return
        old = self.writer.frames()
        keep = old["step"] <= step0
        for k in SERIES:
            self.frames[k] = list(old[k][keep])
        if self.writer.has_checkpoint():
            _, ck_step, attrs = self.writer.load_checkpoint()
            if ck_step == step0:
                self.wall_prev = float(attrs.get("wall_s", 0.0))
                self.realloc_prev = int(attrs.get("n_reallocations", 0))

    def _diagnostics(self, state) -> dict:
        return {k: v.item() for k, v in self.diag_fn(state).items()}

    def _append_frame(self, step: int, d: dict):
        for k, v in (("time", step * self.solver.dt), ("step", step), ("u_max", d["u_max"]),
                     ("e_kin", d["e_kin"]), ("density_error", d["density_error"])):
            self.frames[k].append(v)

    def record(self, state, step: int, d: dict):
        """The frame after `step` (diagnostics `d`); with a writer, also its positions and fields and
        the checkpoint, in the scene's order."""
        self._append_frame(step, d)
        if self.writer is not None:
            state, t = reorder.restore(state, self.order), step * self.solver.dt
            self.writer.append(state, step, t, d)
            self.writer.save_checkpoint(state, step, t, wall_s=self.wall_prev + self.wall,
                                        n_reallocations=self.realloc_prev + self.reallocs)

    def scene_state(self):
        """The current state in the scene's order."""
        return reorder.restore(self.state, self.order)

    def advance(self, n: int) -> Optional[dict]:
        """Take the next `n` steps (sorting the particles first when due) and record their frame;
        returns its diagnostics, or None when the chunk failed in a permuted order (then it is to be
        retried from its start in the scene's order, so that the diagnosis names the scene's
        particles). A failure in the scene's order raises, located and diagnosed."""
        t0, c0 = time.perf_counter(), self.compile_s
        self._reorder_if_due()
        done, error = self._try_chunk(n)
        self.wall += time.perf_counter() - t0 - (self.compile_s - c0)
        if done is None or is_bad(done[3], self.u_limit):
            if self.order is not None:
                self.state, self.order, self.since = reorder.restore(self.state, self.order), None, 0
                self.nbrs = self.solver.neighbors.allocate(self.state.r)
                return None
            raise locate_blowup(self.solver, self.chunk, self.diag_fn, self.state, self.nbrs, self.step, n,
                                 self.writer, error, self.u_limit)
        self.state, self.nbrs, r, d = done
        self.reallocs += r
        self.step, self.since = self.step + n, self.since + n
        self.record(self.state, self.step, d)
        return d

    def _reorder_if_due(self):
        """Sort the fluid particles by cell and rebuild the list, when `reorder_every` steps have
        passed since the last sort (or the run resumed)."""
        if self.reorder_every and self.since >= self.reorder_every:
            perm = reorder.cell_permutation(self.state.r, self.movable, self.solver.scene.dx)
            self.state, self.order = reorder.permute(self.state, perm), reorder.compose(self.order, perm)
            self.nbrs = _rebuilt(self.solver.neighbors, self.rebuild, self.state.r, self.nbrs)
            self.since, self.n_reorders = 0, self.n_reorders + 1

    def _try_chunk(self, n: int):
        """((state, nbrs, re-allocations, diagnostics), None) after `n` steps, or (None, error) when the
        guard refused a step in a permuted order or the list kept overflowing; a guard's refusal in
        the scene's order is raised at once, naming where the last good frame is kept."""
        try:
            if self.sharded is not None:
                (state, r), nbrs = self.sharded.advance(self.step, n), self.nbrs
            else:
                state, nbrs, r = advance(self.chunk, self.solver.neighbors, self.state, self.nbrs, self.step, n,
                                         self.max_reallocations)
            jax.block_until_ready(state)
            return (state, nbrs, r, self._diagnostics(state)), None
        except SimulationError as e:  # the guard refused a step (diagnosed), or overflow kept recurring
            if self.order is None:
                raise with_checkpoint(e, self.solver, self.step, self.writer) from None
            return None, e
        except RuntimeError as e:  # repeated neighbour overflow without a guard
            return None, e

    def result(self, step0: int) -> RunResult:
        """The run's frames and timings, its state and list back in the scene's order."""
        state, nbrs = self.state, self.nbrs
        if self.sharded is not None:  # the global list was not kept up to date on the devices
            nbrs = self.solver.neighbors.allocate(state.r)
        if self.order is not None:
            state = reorder.restore(state, self.order)
            nbrs = _rebuilt(self.solver.neighbors, self.rebuild, state.r, nbrs)
        arrays = {k: np.asarray(v) for k, v in self.frames.items()}
        return RunResult(t=arrays["time"], step=arrays["step"].astype(np.int64), u_max=arrays["u_max"],
                         e_kin=arrays["e_kin"], density_error=arrays["density_error"], wall_s=self.wall,
                         compile_s=self.compile_s, n_steps=self.step - step0, n_reallocations=self.reallocs,
                         wall_s_total=self.wall_prev + self.wall,
                         n_reallocations_total=self.realloc_prev + self.reallocs, step_end=self.step,
                         write_every=self.write_every, state=state, nbrs=nbrs, n_reorders=self.n_reorders,
                         decomposition=self.sharded.describe() if self.sharded is not None else None)


def _rebuilt(neighbors, rebuild, r, nbrs):
    """The list rebuilt at positions r with its capacities (a fresh allocation if they no longer
    suffice): its reference positions are moved past the skin threshold so that `update` rebuilds."""
    shift = neighbors.skin if neighbors.skin > 0 else 0.5 * neighbors.cutoff
    stale = dataclasses.replace(nbrs, reference_position=r.at[0, 0].add(shift))
    new = rebuild(r, stale)
    return neighbors.allocate(r) if bool(new.did_buffer_overflow) else new
