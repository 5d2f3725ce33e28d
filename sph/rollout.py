"""Rollouts with `lax.scan`, safe against neighbour-list overflow.

`make_chunk(step_fn, length)` scans up to `length` steps. A step whose neighbour update overflows is
not taken: the carry keeps the last good state and list, and the chunk reports how many steps it
did. The caller (`advance`) then re-allocates the list outside `jit` and continues from exactly that
state, so an overflow never produces a wrong step and never loses one.
"""
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


def scan_rollout(step_fn, state, nbrs, n_steps: int, step0: int = 0, segments: int = 0):
    """Differentiable rollout of `n_steps` (static) with `lax.scan`.

    Returns (state, nbrs, overflowed). Use `jax.grad` through it; if `overflowed` is true the result
    is invalid and the caller must re-allocate `nbrs` and redo the rollout.

    `segments` > 0 turns on gradient checkpointing: the steps are split into that many segments of
    ceil(n_steps / segments) steps, each wrapped in `jax.checkpoint`, so the backward pass stores one
    carry per segment and recomputes the steps inside a segment. With segments ~ sqrt(n_steps) the
    memory of the gradient grows like sqrt(n_steps) instead of n_steps, for one extra forward pass.
    The result is the same computation, so gradients agree with the plain rollout to round-off.
    """

    def body(carry, k):
        state, nbrs, overflow = carry
        state, nbrs = step_fn(state, nbrs, step0 + k + 1)
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
