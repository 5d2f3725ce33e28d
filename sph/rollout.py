"""Rollouts with `lax.scan`, safe against neighbour-list overflow.

`make_chunk(step_fn, length)` scans up to `length` steps. A step whose neighbour update overflows is
not taken: the carry keeps the last good state and list, and the chunk reports how many steps it
did. The caller (`advance`) then re-allocates the list outside `jit` and continues from exactly that
state, so an overflow never produces a wrong step and never loses one.

`scan_rollout` is the differentiable rollout (one list of fixed capacity, optional gradient
checkpointing over segments and per step). `value_and_grad_rollout` differentiates a loss through it
and never returns a gradient of an overflowed rollout: it checks the overflow flag outside `jit`,
sizes a list for the whole trajectory (`size_list`) and recomputes.
"""
from typing import NamedTuple

import jax
import jax.numpy as jnp


def _select(pred, a, b):
    return jax.tree_util.tree_map(lambda x, y: jnp.where(pred, x, y), a, b)


def make_chunk(step_fn, length: int):
    """chunk(state, nbrs, step0, n_target) -> (state, nbrs, n_done, overflowed)."""

    def chunk(state, nbrs, step0, n_target):
        def body(carry, _):
            state, nbrs, n_done, overflow = carry
            active = (n_done < n_target) & ~overflow
            new_state, new_nbrs = step_fn(state, nbrs, step0 + n_done + 1)
            bad = new_nbrs.did_buffer_overflow.astype(bool)
            take = active & ~bad
            state = _select(take, new_state, state)
            nbrs = _select(take, new_nbrs, nbrs)
            return (state, nbrs, n_done + take.astype(n_done.dtype), overflow | (active & bad)), None

        init = (state, nbrs, jnp.zeros((), jnp.int32), jnp.zeros((), bool))
        (state, nbrs, n_done, overflow), _ = jax.lax.scan(body, init, None, length=length)
        return state, nbrs, n_done, overflow

    return chunk


def advance(chunk, neighbors, state, nbrs, step0: int, n: int, max_reallocations: int = 10):
    """Advance exactly `n` steps from global step `step0` with a jitted `chunk`, re-allocating the
    neighbour list whenever it overflows. Returns (state, nbrs, n_reallocations)."""
    done_total, reallocs = 0, 0
    while done_total < n:
        state, nbrs, done, overflow = chunk(state, nbrs, step0 + done_total, n - done_total)
        done_total += int(done)
        if bool(overflow):
            reallocs += 1
            if reallocs > max_reallocations:
                raise RuntimeError(f"neighbour list overflowed {reallocs} times in a row near step {step0 + done_total}")
            nbrs = neighbors.allocate(state.r)
    return state, nbrs, reallocs


def scan_rollout(step_fn, state, nbrs, n_steps: int, step0: int = 0, segments: int = 0,
                 remat_steps: bool = False):
    """Differentiable rollout of `n_steps` (static) with `lax.scan`.

    Returns (state, nbrs, overflowed). Use `jax.grad` through it; if `overflowed` is true the result
    is invalid and the caller must re-allocate `nbrs` and redo the rollout.

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
    step = jax.checkpoint(step_fn, prevent_cse=False) if remat_steps else step_fn

    def body(carry, k):
        state, nbrs, overflow = carry
        state, nbrs = step(state, nbrs, step0 + k + 1)
        return (state, nbrs, overflow | nbrs.did_buffer_overflow.astype(bool)), None

    def run(carry, ks):
        return jax.lax.scan(body, carry, ks)[0], None

    carry = (state, nbrs, jnp.zeros((), bool))
    if segments <= 0 or segments >= n_steps:
        carry, _ = run(carry, jnp.arange(n_steps))
        return carry
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
    skin / 2 from where the list was built, so `initial_state` may have missed pairs).
    Wrap it in `jax.jit(jax.value_and_grad(objective, has_aux=True))`.
    """

    def objective(params, nbrs):
        state = initial_state(params, nbrs)
        checked = neighbors.update(state.r, nbrs)
        stale = jnp.any(checked.reference_position != nbrs.reference_position)
        invalid0 = stale | checked.did_buffer_overflow.astype(bool)
        state, _, overflowed = scan_rollout(step_fn, state, nbrs, n_steps, step0=step0, segments=segments,
                                            remat_steps=remat_steps)
        out = loss_fn(state)
        loss, aux = out if has_aux else (out, None)
        return loss, (aux, invalid0 | overflowed)

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
        u0 = jnp.asarray(solver.scene.u, solver.dtype)

        def initial_state(r, nbrs):
            return solver.state_at(r, u0, nbrs)

    objective = rollout_objective(loss_fn, initial_state, solver.step_fn, solver.neighbors, n_steps,
                                  step0=step0, segments=segments, has_aux=has_aux, remat_steps=remat_steps)
    value_and_grad = jax.jit(jax.value_and_grad(objective, has_aux=True))
    start = jax.jit(initial_state)
    compiled = {}

    def sizing_fns():
        if not compiled:
            compiled["chunk"] = jax.jit(make_chunk(solver.step_fn, n_steps))
            compiled["next"] = jax.jit(lambda s, nb, k: solver.step_fn(s, nb, k)[0].r)
        return compiled["chunk"], compiled["next"]

    def run(params, nbrs=None):
        reallocs = 0
        if nbrs is None:
            # the positions do not depend on the list: build the state with any list, then allocate
            r0 = start(params, solver.neighbors.allocate(jnp.asarray(solver.scene.r, solver.dtype))).r
            nbrs = solver.neighbors.allocate(r0)
        while True:
            (loss, (aux, invalid)), grad = value_and_grad(params, nbrs)
            if not bool(invalid):
                return RolloutGradient(loss, grad, aux, nbrs, reallocs)
            if reallocs >= max_reallocations:
                raise RuntimeError(
                    f"value_and_grad_rollout: the neighbour list still overflowed (or was stale at the "
                    f"initial positions) after {reallocs} re-allocations (capacity {_capacity(nbrs)} "
                    f"(slots, cell slots), {n_steps} steps); raise max_reallocations or the capacity")
            state0 = start(params, nbrs)  # positions only; the list is rebuilt at them below
            chunk, next_positions = sizing_fns()
            floor = tuple(c + 1 for c in _capacity(nbrs))  # the last list was too small somewhere
            cap, n = size_list(solver.step_fn, solver.neighbors, state0, n_steps, step0, floor,
                               max_reallocations - reallocs - 1, chunk, next_positions)
            reallocs += 1 + n
            nbrs = allocate_covering(solver.neighbors, state0.r, cap)

    return run
