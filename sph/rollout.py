"""Rollouts with `lax.scan`, safe against neighbour-list overflow.

`make_chunk(step_fn, length)` scans up to `length` steps. A step whose neighbour update overflows is
not taken: the carry keeps the last good state and list, and the chunk reports how many steps it
did. The caller (`advance`) then re-allocates the list outside `jit` and continues from exactly that
state, so an overflow never produces a wrong step and never loses one.

`scan_rollout` is the differentiable rollout (one list of fixed capacity, optional gradient
checkpointing over segments and per step). `value_and_grad_rollout` differentiates a loss through it
and never returns a gradient of an overflowed rollout: it checks the overflow flag outside `jit`,
sizes a list for the whole trajectory (`size_list`) and recomputes.

The step guard (`sph.guard.StepGuard`, `solver.guard`): `make_chunk(..., guard=g)` refuses a
step after which a fluid particle is outside the domain in a non-periodic dimension, moves faster
than the guard's speed limit or has a non-finite velocity or density; the chunk then stops with the
last good state and `advance` raises the guard's diagnosis (`ParticleEscaped`, `BlowUp`), naming the
step, the particle and its position. `scan_rollout` applies the guard that `solver.step_fn` carries
(`step_fn.guard`) by default and reports a refused rollout like an overflowed one;
`value_and_grad_rollout` raises the diagnosis instead of returning that gradient.
"""
from typing import NamedTuple

import jax
import jax.numpy as jnp

from .errors import NeighborOverflow


def _select(pred, a, b):
    return jax.tree_util.tree_map(lambda x, y: jnp.where(pred, x, y), a, b)


def make_chunk(step_fn, length: int, guard=None):
    """chunk(state, nbrs, step0, n_target) -> (state, nbrs, n_done, overflowed).

    With a `guard` (`sph.guard.StepGuard`, e.g. `solver.guard`) a step the guard rejects is
    not taken either: the chunk stops there with the last good state, n_done < n_target and
    overflowed false (`advance` raises the guard's diagnosis). The guard rides along as
    `chunk.guard` (kept by `jax.jit`)."""

    def chunk(state, nbrs, step0, n_target):
        def body(carry, _):
            state, nbrs, n_done, overflow, stopped = carry
            active = (n_done < n_target) & ~overflow & ~stopped
            new_state, new_nbrs = step_fn(state, nbrs, step0 + n_done + 1)
            bad = new_nbrs.did_buffer_overflow.astype(bool)
            refused = ~bad & guard.reject(new_state) if guard is not None else jnp.zeros((), bool)
            take = active & ~bad & ~refused
            state = _select(take, new_state, state)
            nbrs = _select(take, new_nbrs, nbrs)
            return (state, nbrs, n_done + take.astype(n_done.dtype), overflow | (active & bad),
                    stopped | (active & refused)), None

        init = (state, nbrs, jnp.zeros((), jnp.int32), jnp.zeros((), bool), jnp.zeros((), bool))
        (state, nbrs, n_done, overflow, _), _ = jax.lax.scan(body, init, None, length=length)
        return state, nbrs, n_done, overflow

    chunk.guard, chunk.length = guard, length
    return chunk


def advance(chunk, neighbors, state, nbrs, step0: int, n: int, max_reallocations: int = 10):
    """Advance exactly `n` steps from global step `step0` with a jitted `chunk`, re-allocating the
    neighbour list whenever it overflows. Returns (state, nbrs, n_reallocations).

    A step refused by the chunk's guard raises the guard's diagnosis (a `SimulationError`: the step,
    the particle, its position, the likely cause; `.state` is the last good state). More than
    `max_reallocations` overflows in a row raise `NeighborOverflow` (diagnosed by the guard if any).
    `n` may exceed the chunk's length: the chunk is called again until n steps are done."""
    done_total, reallocs = 0, 0
    guard, length = getattr(chunk, "guard", None), getattr(chunk, "length", None)
    while done_total < n:
        state, nbrs, done, overflow = chunk(state, nbrs, step0 + done_total, n - done_total)
        done_total += int(done)
        if bool(overflow):
            reallocs += 1
            if reallocs > max_reallocations:
                why = f"the neighbour list overflowed {reallocs} times in a row"
                if guard is not None:
                    raise guard.diagnose(state, nbrs, step0 + done_total + 1, why)
                raise NeighborOverflow(f"{why} near step {step0 + done_total + 1}: particles are clumping, "
                                       "typically the start of a blow-up (check numerics.dt / numerics.cfl)",
                                       step=step0 + done_total + 1, state=state, nbrs=nbrs)
            nbrs = neighbors.allocate(state.r)
        elif done_total < n and (length is None or int(done) < length):  # the guard refused the next step
            raise guard.diagnose(state, nbrs, step0 + done_total + 1)
    return state, nbrs, reallocs


def scan_rollout(step_fn, state, nbrs, n_steps: int, step0: int = 0, segments: int = 0,
                 remat_steps: bool = False, guard="auto", split: bool = False):
    """Differentiable rollout of `n_steps` (static) with `lax.scan`.

    Returns (state, nbrs, overflowed). Use `jax.grad` through it; if `overflowed` is true the result
    is invalid and the caller must re-allocate `nbrs` and redo the rollout.

    `guard` ("auto": `step_fn.guard`, which `solver.step_fn` carries; None: off) flags a rollout in
    which a fluid particle left the domain, exceeded the speed limit or became non-finite
    (`sph.guard.StepGuard`); by default that flag is folded into `overflowed` (the result is
    invalid either way), with `split=True` it is returned apart: (state, nbrs, overflowed, refused).
    A refused rollout is not cured by a larger list: `value_and_grad_rollout` raises the diagnosis.

    `segments` > 0 turns on gradient checkpointing: the steps are split into that many segments of
    ceil(n_steps / segments) steps, each wrapped in `jax.checkpoint`, so the backward pass stores one
    carry per segment and recomputes the steps inside a segment. With segments ~ sqrt(n_steps) the
    memory of the gradient grows like sqrt(n_steps) instead of n_steps, for one extra forward pass.
    The result is the same computation, so gradients agree with the plain rollout to round-off.

    `remat_steps` also wraps every step in `jax.checkpoint`: the backward pass then keeps only each
    step's carry (state and list, ~ (14 + K / 2) numbers per particle in float64) instead of the
    step's pair intermediates (~ 50 numbers per pair, most of a step's residuals), and recomputes those one
    step at a time, for one more forward evaluation of every step. Combined with `segments` (nested
    checkpointing) the gradient memory is about (n_steps / segments + segments) carries plus one
    step's intermediates.
    """
    if isinstance(guard, str) and guard == "auto":
        guard = getattr(step_fn, "guard", None)
    step = jax.checkpoint(step_fn, prevent_cse=False) if remat_steps else step_fn

    def body(carry, k):
        state, nbrs, overflow, refused = carry
        state, nbrs = step(state, nbrs, step0 + k + 1)
        if guard is not None:
            refused = refused | jax.lax.stop_gradient(guard.reject(state))
        return (state, nbrs, overflow | nbrs.did_buffer_overflow.astype(bool), refused), None

    carry = (state, nbrs, jnp.zeros((), bool), jnp.zeros((), bool))
    state, nbrs, overflow, refused = _scan_segments(body, carry, n_steps, segments)
    return (state, nbrs, overflow, refused) if split else (state, nbrs, overflow | refused)


def _scan_segments(body, carry, n_steps: int, segments: int):
    """The carry after scanning `body` over the step numbers 0 .. n_steps-1: in one scan, or, with
    0 < segments < n_steps, in segments of ceil(n_steps / segments) steps, each under `jax.checkpoint`
    (the backward pass keeps one carry per segment and recomputes the steps inside it)."""

    def run(carry, ks):
        return jax.lax.scan(body, carry, ks)[0], None

    if segments <= 0 or segments >= n_steps:
        return run(carry, jnp.arange(n_steps))[0]
    seg = -(-n_steps // segments)
    full = n_steps // seg
    run_ckpt = jax.checkpoint(run)
    carry, _ = jax.lax.scan(run_ckpt, carry, jnp.arange(full * seg).reshape(full, seg))
    if full * seg < n_steps:
        carry, _ = run_ckpt(carry, jnp.arange(full * seg, n_steps))
    return carry


# ---------------------------------------------------------------------------------------------------
# Gradients through a rollout that are never silently wrong
# ---------------------------------------------------------------------------------------------------
#
# A differentiated rollout cannot stop at an overflow and re-allocate inside `jit` the way `advance`
# does: `lax.scan` needs one list of fixed capacity for the whole trajectory. So the rollout runs
# with one list, reports whether it ever overflowed (or whether the list it was given was stale at
# the initial positions), and `value_and_grad_rollout` checks that flag outside `jit`. On overflow
# it sizes a list for the whole trajectory with a cheap forward pass (`size_list`) and redoes the
# differentiated rollout with it.
#
# Why a list sized by the forward pass suffices: jax-md lists overflow only when they are rebuilt,
# and whether (and where) a list is rebuilt depends only on the positions and on the reference
# positions of its last build, never on its capacity. `size_list` starts from a list built at the
# initial positions, exactly as the differentiated pass does, and on an overflow re-allocates at the
# positions of the overflowing step itself, where the rebuild would have happened. Both passes
# therefore rebuild at the same steps and positions; a capacity that is at least the largest one
# allocated at any of these rebuilds (capacities only grow) covers every rebuild of the
# differentiated pass.


def rollout_objective(loss_fn, initial_state, step_fn, neighbors, n_steps: int, step0: int = 0,
                      segments: int = 0, has_aux: bool = False, remat_steps: bool = False):
    """The traceable objective of `value_and_grad_rollout`:

        objective(params, nbrs) -> (loss, (aux, invalid))

    state0 = initial_state(params, nbrs); `n_steps` of `step_fn` with `scan_rollout` (checkpointed
    over `segments`, and per step with `remat_steps`); loss = loss_fn(final state), or
    (loss, aux) = loss_fn(final state) with `has_aux`. `invalid` is true if the list overflowed
    during the rollout, or if it was stale at the initial positions (some particle moved more than
    skin / 2 from where the list was built, so `initial_state` may have missed pairs), or if the
    step guard (`step_fn.guard`) refused a step: an int32 code, 1 for the list, 2 for the guard (3: both).
    Wrap it in `jax.jit(jax.value_and_grad(objective, has_aux=True))`.
    """

    def objective(params, nbrs):
        state = initial_state(params, nbrs)
        checked = neighbors.update(state.r, nbrs)
        stale = jnp.any(checked.reference_position != nbrs.reference_position)
        invalid0 = stale | checked.did_buffer_overflow.astype(bool)
        state, _, overflowed, refused = scan_rollout(step_fn, state, nbrs, n_steps, step0=step0,
                                                     segments=segments, remat_steps=remat_steps, split=True)
        out = loss_fn(state)
        loss, aux = out if has_aux else (out, None)
        code = (invalid0 | overflowed).astype(jnp.int32) + 2 * refused.astype(jnp.int32)
        return loss, (aux, code)

    return objective


def _capacity(nbrs):
    """(neighbour slots per particle, cell-list slots per cell) of a jax-md list (0: no cell list)."""
    return nbrs.max_occupancy, nbrs.cell_list_capacity or 0


def allocate_covering(neighbors, r, capacity=(0, 0)):
    """A list built at `r` with at least `capacity` = (neighbour slots, cell slots); jax-md's
    `extra_capacity` adds to both."""
    nbrs = neighbors.allocate(r)
    k, c = _capacity(nbrs)
    extra = max(capacity[0] - k, capacity[1] - c if nbrs.cell_list_capacity is not None else 0, 0)
    return neighbors.allocate(r, extra_capacity=extra) if extra else nbrs


def size_list(step_fn, neighbors, state0, n_steps: int, step0: int = 0, capacity=(0, 0),
              max_reallocations: int = 10, chunk=None, next_positions=None):
    """Capacity a single list needs for the whole rollout of `n_steps` from `state0` (not
    differentiated, not jitted itself). Returns ((slots, cell slots), n_reallocations).

    The list starts at `state0.r` with at least `capacity`; at every overflow the list is
    re-allocated at the positions of the overflowing step, with at least the capacity so far, and the
    rollout continues from the last good state (see the note above). `chunk` / `next_positions` are
    the jitted `make_chunk(step_fn, n_steps)` and `state, nbrs, step -> step_fn(...)[0].r`, passed in
    to reuse compilations across calls.
    """
    chunk = chunk or jax.jit(make_chunk(step_fn, n_steps))
    next_positions = next_positions or jax.jit(lambda s, nb, k: step_fn(s, nb, k)[0].r)
    nbrs = allocate_covering(neighbors, state0.r, capacity)
    cap = _capacity(nbrs)
    state, done, reallocs = state0, 0, 0
    while True:
        state, nbrs, n_done, overflow = chunk(state, nbrs, step0 + done, n_steps - done)
        done += int(n_done)
        if not bool(overflow):
            return cap, reallocs
        reallocs += 1
        if reallocs > max_reallocations:
            raise RuntimeError(f"size_list: the neighbour list overflowed {reallocs} times; last at step "
                               f"{step0 + done + 1} with capacity {cap} (slots, cell slots)")
        nbrs = allocate_covering(neighbors, next_positions(state, nbrs, step0 + done + 1), cap)
        cap = tuple(max(a, b) for a, b in zip(cap, _capacity(nbrs)))


class RolloutGradient(NamedTuple):
    """value: loss; grad: d loss / d params; aux: loss_fn's aux (None without has_aux); nbrs: the list
    the valid pass used (reuse it in the next call); reallocations: lists re-allocated (0: the given
    list was valid throughout)."""

    value: jax.Array
    grad: object
    aux: object
    nbrs: object
    reallocations: int


def value_and_grad_rollout(loss_fn, solver, n_steps: int, initial_state=None, step0: int = 0,
                           segments: int = 0, has_aux: bool = False, max_reallocations: int = 4,
                           remat_steps: bool = False):
    """Loss and gradient through a rollout, re-allocating the neighbour list until the rollout is valid.

        vg = value_and_grad_rollout(loss_fn, solver, n_steps, segments=...)
        res = vg(params, nbrs)      # RolloutGradient(value, grad, aux, nbrs, reallocations)

    loss_fn(state) -> scalar (or (scalar, aux) with `has_aux`) of the state after `n_steps` steps.
    initial_state(params, nbrs) -> state, traceable in `params`; default: params are the initial
    positions and the velocities are the scene's, `solver.state_at(params, u0, nbrs)`.
    `nbrs` may be None (a list is allocated at the initial positions).

    The rollout is differentiated in one jitted pass (`rollout_objective`, checkpointed over
    `segments` and with `remat_steps`, see `scan_rollout`). If the list overflowed anywhere in it, or
    was stale at the initial positions, the result is discarded: the capacity needed for the whole
    trajectory is found with a forward pass (`size_list`), a list with that capacity is allocated at
    the initial positions and the gradient is recomputed. The returned gradient is therefore always
    that of a rollout without overflow, identical (to round-off) to one run with an ample list from
    the start. More than `max_reallocations` re-allocations raise a RuntimeError.
    """
    if initial_state is None:
        initial_state = _start_with_scene_velocities(solver)
    objective = rollout_objective(loss_fn, initial_state, solver.step_fn, solver.neighbors, n_steps,
                                  step0=step0, segments=segments, has_aux=has_aux, remat_steps=remat_steps)
    value_and_grad = jax.jit(jax.value_and_grad(objective, has_aux=True))
    start = jax.jit(initial_state)
    sizer = _ListSizer(solver, n_steps, step0)

    def run(params, nbrs=None):
        reallocs = 0
        if nbrs is None:
            nbrs = _list_at_start(solver, start, params)
        while True:
            (loss, (aux, invalid)), grad = value_and_grad(params, nbrs)
            if not int(invalid):
                return RolloutGradient(loss, grad, aux, nbrs, reallocs)
            if int(invalid) & 2:
                raise _refused(solver, start(params, nbrs), n_steps, step0)
            if reallocs >= max_reallocations:
                raise RuntimeError(
                    f"value_and_grad_rollout: the neighbour list still overflowed (or was stale at the "
                    f"initial positions) after {reallocs} re-allocations (capacity {_capacity(nbrs)} "
                    f"(slots, cell slots), {n_steps} steps); raise max_reallocations or the capacity")
            state0 = start(params, nbrs)  # positions only; the list is rebuilt at them below
            nbrs, n = sizer.covering_list(state0, nbrs, max_reallocations - reallocs - 1)
            reallocs += 1 + n

    return run


def _list_at_start(solver, start, params):
    """A list allocated at the initial positions start(params, .).r; they do not depend on the list,
    so the state is built with any list (one at the scene's positions) first."""
    r0 = start(params, solver.neighbors.allocate(jnp.asarray(solver.scene.r, solver.dtype))).r
    return solver.neighbors.allocate(r0)


def _start_with_scene_velocities(solver):
    """initial_state(r, nbrs): the state at positions r with the scene's velocities."""
    u0 = jnp.asarray(solver.scene.u, solver.dtype)

    def initial_state(r, nbrs):
        return solver.state_at(r, u0, nbrs)

    return initial_state


class _ListSizer:
    """Lists that cover a whole rollout of `n_steps` from `step0` (`size_list`), with the forward
    chunk and step it needs jitted once, on first use."""

    def __init__(self, solver, n_steps: int, step0: int):
        self.solver, self.n_steps, self.step0 = solver, n_steps, step0
        self.chunk = self.next_positions = None

    def covering_list(self, state0, nbrs, max_reallocations: int):
        """(a list at state0.r larger than `nbrs` and covering the rollout from state0, the
        re-allocations the sizing pass took)."""
        step_fn = self.solver.step_fn
        if self.chunk is None:
            self.chunk = jax.jit(make_chunk(step_fn, self.n_steps))
            self.next_positions = jax.jit(lambda s, nb, k: step_fn(s, nb, k)[0].r)
        floor = tuple(c + 1 for c in _capacity(nbrs))  # the last list was too small somewhere
        cap, n = size_list(step_fn, self.solver.neighbors, state0, self.n_steps, self.step0, floor,
                           max_reallocations, self.chunk, self.next_positions)
        return allocate_covering(self.solver.neighbors, state0.r, cap), n


def _refused(solver, state0, n_steps: int, step0: int) -> RuntimeError:
    """The guard refused a step of the differentiated rollout from `state0`: find and name it (forward
    pass with the guard, `advance`)."""
    guard = getattr(solver.step_fn, "guard", None)
    chunk = jax.jit(make_chunk(solver.step_fn, n_steps, guard=guard))
    try:
        advance(chunk, solver.neighbors, state0, solver.neighbors.allocate(state0.r), step0, n_steps)
    except RuntimeError as e:
        err = type(e)(f"value_and_grad_rollout: no gradient for this rollout: {e}")
        err.__dict__.update(e.__dict__)
        return err
    return RuntimeError("value_and_grad_rollout: the step guard refused a step of the differentiated rollout "
                        "but not of the forward pass (round-off at the domain edge?); no gradient returned")
