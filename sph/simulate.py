"""Simulation driver: advance a solver in chunks, record a frame after each, write, resume.

`run(solver, state, nbrs, t_end, write_every, writer)` advances `write_every` steps per jitted chunk
(`sph.rollout.make_chunk` + `advance`, so neighbour-list overflow re-allocates and never loses a
step). After every chunk it records a frame (t, u_max, E_kin, max density error; positions and
kept fields go to the optional writer, `sph.harness.io.TrajectoryWriter`) and overwrites its
checkpoint, so an interrupted run continues with `resume(solver, writer)` + `run(..., step0=step)`.

Timing: the chunk is compiled ahead of every call with new shapes (`jit(...).lower(...).compile()`,
which fills the same cache the calls use, without taking a step): before the loop and again after a
neighbour re-allocation changes the list's capacity. That time is `compile_s`; `wall_s` is the
solve time of the chunks only, each synchronised with `block_until_ready`, compilation excluded.

Every step is guarded (`solver.guard`, `sph.diagnostics.StepGuard`, on by default): a step after
which a fluid particle is outside the domain in a non-periodic dimension (`ParticleEscaped`), a
fluid speed exceeds `u_limit` (default: the artificial sound speed c_ref, a finite blow-up) or a
velocity or density is non-finite (`BlowUp`) is not taken; the neighbour list overflowing again
and again is `NeighborOverflow`. `run` then raises that `SimulationError` (a RuntimeError) naming
the step, the time, the particle, its position and the likely cause (dt against its limits); a bad
state the guard does not see (another field non-finite) is found at the end of the chunk and
located by bisecting the chunk from its last good state. The writer keeps the last good frame and
its checkpoint, and the message says where.

Particle order (`reorder_every`, default numerics.reorder_every; `sph.reorder`): every that many
steps (at the next frame) the fluid particles are sorted by cell among their slots and the
neighbour list is rebuilt, so that the gathers of the pair sums stay local as the flow mixes the
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
from .diagnostics import SimulationError
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

    @property
    def ms_per_step(self) -> float:
        return 1e3 * self.wall_s / self.n_steps if self.n_steps else float("nan")


class _CompiledChunk:
    """A jitted chunk that compiles (timed) before its first call with each new argument signature,
    so compilation is measured apart from execution even when `advance` re-allocates mid-chunk."""

    def __init__(self, jitted):
        self.jitted = jitted
        self.guard = getattr(jitted, "guard", None)  # make_chunk's step guard, for `advance`
        self.seen = set()
        self.compile_s = 0.0

    @staticmethod
    def _signature(args):
        leaves, treedef = jax.tree_util.tree_flatten(args)
        return treedef, tuple((np.shape(x), str(getattr(x, "dtype", type(x).__name__))) for x in leaves)

    def compile(self, *args):
        sig = self._signature(args)
        if sig not in self.seen:
            t0 = time.perf_counter()
            self.jitted.lower(*args).compile()
            self.compile_s += time.perf_counter() - t0
            self.seen.add(sig)

    def __call__(self, *args):
        self.compile(*args)
        return self.jitted(*args)


def resume(solver, writer):
    """(state, nbrs, step) from the checkpoint of `writer`, with a freshly allocated neighbour list."""
    state, step, _ = writer.load_checkpoint()
    return state, solver.neighbors.allocate(state.r), step


def run(solver, state, nbrs, t_end: float, write_every: int, writer=None, progress: bool = True,
        step0: int = 0, *, n_steps: Optional[int] = None, callback: Optional[Callable] = None,
        desc: Optional[str] = None, max_reallocations: int = 10, u_limit: Optional[float] = None,
        reorder_every: Optional[int] = None) -> RunResult:
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
    """
    if write_every < 1:
        raise ValueError(f"write_every must be >= 1, got {write_every}")
    n_total = solver.n_steps(t_end) if n_steps is None else int(n_steps)
    if not 0 <= step0 <= n_total:
        raise ValueError(f"step0={step0} is outside [0, {n_total}]")
    dt = solver.dt
    rho_ref = solver.scene.material.rho_ref
    if u_limit is None:
        u_limit = solver.c_ref
    guard = solver.guard.with_limit(u_limit) if solver.guard is not None else None
    chunk = _CompiledChunk(jax.jit(make_chunk(solver.step_fn, write_every, guard=guard)))
    if reorder_every is None:
        reorder_every = solver.numerics.reorder_every
    if reorder_every < 0:
        raise ValueError(f"reorder_every must be >= 0, got {reorder_every}")
    movable = reorder.movable_mask(solver.scene) if reorder_every else None
    rebuild = _CompiledChunk(jax.jit(solver.neighbors.update)) if reorder_every else None
    order, since, n_reorders = None, 0, 0  # order[i]: the scene's number of the particle in slot i
    diag_fn = jax.jit(partial(diagnostics.summary, rho_ref=rho_ref))

    frames = {k: [] for k in SERIES}
    wall_prev, realloc_prev = 0.0, 0
    if writer is not None and step0 > 0:
        old = writer.frames()
        keep = old["step"] <= step0
        for k in SERIES:
            frames[k] = list(old[k][keep])
        if writer.has_checkpoint():
            _, ck_step, attrs = writer.load_checkpoint()
            if ck_step == step0:
                wall_prev = float(attrs.get("wall_s", 0.0))
                realloc_prev = int(attrs.get("n_reallocations", 0))

    t0 = time.perf_counter()
    diag_fn.lower(state).compile()
    compile_s = time.perf_counter() - t0
    wall, reallocs = 0.0, 0

    def record(state, step, d):
        t = step * dt
        for k, v in (("time", t), ("step", step), ("u_max", d["u_max"]), ("e_kin", d["e_kin"]),
                     ("density_error", d["density_error"])):
            frames[k].append(v)
        state = reorder.restore(state, order)
        if writer is not None:
            writer.append(state, step, t, d)
            writer.save_checkpoint(state, step, t, wall_s=wall_prev + wall,
                                   n_reallocations=realloc_prev + reallocs)

    d0 = {k: v.item() for k, v in diag_fn(state).items()}
    if d0["first_nonfinite"] >= 0:
        i = int(d0["first_nonfinite"])
        raise RuntimeError(f"the state at step {step0} (t={step0 * dt:.6g}) is not finite: particle {i} "
                           f"has non-finite {diagnostics.nonfinite_fields(state, i)}")
    if step0 == 0 and (writer is None or writer.n_frames == 0):
        record(state, 0, d0)
    elif not frames["step"]:
        for k, v in (("time", step0 * dt), ("step", step0), ("u_max", d0["u_max"]), ("e_kin", d0["e_kin"]),
                     ("density_error", d0["density_error"])):
            frames[k].append(v)

    # Compile without advancing: lower + compile fills the cache that the calls below hit.
    if step0 < n_total:
        chunk.compile(state, nbrs, step0, min(write_every, n_total - step0))
        if rebuild is not None:
            rebuild.compile(state.r, nbrs)
    compile_s += chunk.compile_s + (rebuild.compile_s if rebuild is not None else 0.0)
    chunk.compile_s = 0.0

    step = step0
    bar = tqdm(total=n_total, initial=step0, disable=not progress, desc=desc, unit="step",
               mininterval=2.0, dynamic_ncols=True)
    try:
        while step < n_total:
            n = min(write_every, n_total - step)
            t0, c0 = time.perf_counter(), chunk.compile_s + (rebuild.compile_s if rebuild is not None else 0.0)
            if reorder_every and since >= reorder_every:
                perm = reorder.cell_permutation(state.r, movable, solver.scene.dx)
                state, order = reorder.permute(state, perm), reorder.compose(order, perm)
                nbrs = _rebuilt(solver.neighbors, rebuild, state.r, nbrs)
                since, n_reorders = 0, n_reorders + 1
            try:
                new_state, new_nbrs, r = advance(chunk, solver.neighbors, state, nbrs, step, n, max_reallocations)
                jax.block_until_ready(new_state)
                d = {k: v.item() for k, v in diag_fn(new_state).items()}
                bad, error = _is_bad(d, u_limit), None
            except SimulationError as e:  # the guard refused a step (diagnosed), or overflow kept recurring
                if order is not None:
                    bad, error = True, e
                else:
                    raise _with_checkpoint(e, solver, step, writer) from None
            except RuntimeError as e:  # repeated neighbour overflow without a guard
                bad, error = True, e
            wall += time.perf_counter() - t0 - (chunk.compile_s + (rebuild.compile_s if rebuild is not None else 0.0) - c0)
            if bad and order is not None:  # retry from the chunk's start in the scene's order (diagnoses name
                state, order, since = reorder.restore(state, order), None, 0  # the scene's particles)
                nbrs = solver.neighbors.allocate(state.r)
                continue
            if bad:
                raise _locate_blowup(solver, chunk, diag_fn, state, nbrs, step, n, writer, error, u_limit)
            reallocs += r
            state, nbrs, step, since = new_state, new_nbrs, step + n, since + n
            record(state, step, d)
            bar.update(n)
            bar.set_postfix(t=f"{step * dt:.3g}", u_max=f"{d['u_max']:.4g}", refresh=False)
            if callback is not None:
                callback(step, step * dt, reorder.restore(state, order))
    finally:
        bar.close()
    if order is not None:
        state = reorder.restore(state, order)
        nbrs = _rebuilt(solver.neighbors, rebuild, state.r, nbrs)

    arrays = {k: np.asarray(v) for k, v in frames.items()}
    return RunResult(t=arrays["time"], step=arrays["step"].astype(np.int64), u_max=arrays["u_max"],
                     e_kin=arrays["e_kin"], density_error=arrays["density_error"], wall_s=wall,
                     compile_s=compile_s + chunk.compile_s, n_steps=step - step0, n_reallocations=reallocs,
                     wall_s_total=wall_prev + wall, n_reallocations_total=realloc_prev + reallocs,
                     step_end=step, write_every=write_every, state=state, nbrs=nbrs, n_reorders=n_reorders)


def _rebuilt(neighbors, rebuild, r, nbrs):
    """The list rebuilt at positions r with its capacities (a fresh allocation if they no longer
    suffice): its reference positions are moved past the skin threshold so that `update` rebuilds."""
    shift = neighbors.skin if neighbors.skin > 0 else 0.5 * neighbors.cutoff
    stale = dataclasses.replace(nbrs, reference_position=r.at[0, 0].add(shift))
    new = rebuild(r, stale)
    return neighbors.allocate(r) if bool(new.did_buffer_overflow) else new


def _is_bad(d: dict, u_limit: Optional[float]) -> bool:
    return int(d["first_nonfinite"]) >= 0 or (u_limit is not None and float(d["u_max"]) > u_limit)


def _with_checkpoint(err: SimulationError, solver, step: int, writer) -> SimulationError:
    """`err` with the note where the last good frame (`step`, the start of the chunk) is kept."""
    if writer is None:
        return err
    out = type(err)(f"{err}; the last good frame (step {step}, t={step * solver.dt:.6g}) is kept in the "
                    f"checkpoint of {writer.path}")
    out.__dict__.update(err.__dict__)
    return out


def _locate_blowup(solver, chunk, diag_fn, state, nbrs, step, n, writer, error, u_limit) -> RuntimeError:
    """The chunk from the good `state` at `step` went bad within `n` steps: bisect for the first bad
    step, take it once more unguarded and name the first offending particle (`StepGuard.diagnose`)."""

    def advance_ok(m):
        try:
            s, nb, _ = advance(chunk, solver.neighbors, state, nbrs, step, m)
        except RuntimeError:
            return None
        return None if _is_bad(diag_fn(s), u_limit) else (s, nb)

    lo, hi = 0, n  # after lo steps good, after hi steps not
    good = (state, nbrs)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        res = advance_ok(mid)
        if res is None:
            hi = mid
        else:
            lo, good = mid, res
    s_good, nb_good = good
    bad_step = step + lo + 1
    guard = solver.guard.with_limit(u_limit)
    err = guard.diagnose(s_good, nb_good, bad_step, why=str(error) if error is not None else "")
    err.__cause__ = error
    return _with_checkpoint(err, solver, step, writer)
