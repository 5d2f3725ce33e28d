"""A pass over the neighbour list, evaluated in cache-sized blocks of particles (rows).

Written over the whole (N, K) list, every pair quantity of a pass (r_ij, |r_ij|, W, the gathered
neighbour fields, the pair terms) would be an (N, K) array that XLA's CPU backend materialises
between its fusions: at 50^3 particles and K = 231 slots each is 230 MB, and a step streams dozens
of them through memory. `evaluate` instead runs the pass for B particles at a time (a `lax.map`
over blocks of about BLOCK_PAIRS slots), so the pairs of one block stay in cache and are never all
allocated at once. The per-particle inputs are prepared once per pass (`Particles.columns`); each
block slices its own rows (`Own`) and gathers its neighbours' (`Nbr`). Every row is computed with
the same operations as over the whole list, so results do not depend on the block size beyond
round-off.

Blocks are B consecutive rows, B evened out over the blocks (ceil(N / ceil(N / B)): 6400 rows at a
target of 5242 are two blocks of 3200, not 5242 + 5242); when B does not divide N, the last block is
shifted back to end at row N (it overlaps the one before, and only its new rows are kept), so no
row is padded or fabricated. A list that fits in one block is evaluated directly.
"""
import jax
import jax.numpy as jnp

from .pvec import PVec
from .views import Nbr, Own, rows

BLOCK_PAIRS = 1 << 17
"""Neighbour slots per block (read when a step is traced): 1 MB of float64 per pair quantity. The
TVF force pass keeps more pair quantities live than standard SPH; at 2^18 slots its block no longer
stays in cache (3D 32^3, CPU time of the force pass: TVF 2^18 196 ms, 2^17 160 ms, 2^16 157 ms;
standard SPH 93 / 83 / 86 ms)."""


def block_rows(n: int, k: int) -> int:
    """Rows per block for N particles with K slots each (N: a single block)."""
    target = max(1, BLOCK_PAIRS // max(k, 1))
    if target >= n:
        return n
    return -(-n // -(-n // target))


def over_rows(body, idx):
    """body(start, size, idx_rows) -> pytree of (size, ...) per-row arrays, for every block of rows of
    `idx` (size None: all rows at once); the blocks' rows joined in order, (N, ...)."""
    n, k = idx.shape
    b = block_rows(n, k)
    if b >= n:
        return body(0, None, idx)
    nb = -(-n // b)
    starts = jnp.minimum(jnp.arange(nb) * b, n - b)
    out = jax.lax.map(lambda s: body(s, b, jax.lax.dynamic_slice_in_dim(idx, s, b)), starts)
    keep = n - (nb - 1) * b       # the last block's rows that the one before does not hold

    def join(x):
        return jnp.concatenate([x[:-1].reshape((-1,) + x.shape[2:]), x[-1, b - keep:]])

    return jax.tree_util.tree_map(join, out)


def evaluate(term, particles, idx, geometry):
    """Per-particle results of `term(pairs, i, j)` over the neighbour list `idx`, in blocks.

    `particles` (sph.views.Particles) holds the per-particle inputs, `geometry(r_own, r_all, idx_rows)`
    builds the block's `Pairs`. The term returns per-row values ((B, 1) arrays, PVecs, or a pytree of
    them); they come back as (N,) and (N, dim) arrays in the same pytree."""
    cols = particles.columns()

    def block(start, size, idx_rows):
        i = Own(cols, start, size)
        pp = geometry(i.r, cols.r, idx_rows)
        out = term(pp, i, Nbr(cols, pp.j))
        return jax.tree_util.tree_map(rows, out, is_leaf=lambda x: isinstance(x, PVec))

    return over_rows(block, idx)
