"""Pair geometry of a block of particles over a dense neighbour list.

With jax-md's Dense format the list `idx` has shape (N, K), padded with N. A pass evaluates its
pairs for a block of B consecutive particles (rows) at a time (`sph.blocks`): the geometry of the
block's B x K pairs is computed here, the neighbours' fields are gathered by `sph.views.Nbr`, and
every pair sum is a reduction over the last axis (no scatter-add). Padded slots get a distance beyond
the kernel support, so W = dW/dr = 0 there and no masking is needed in the physics; distances use a
safe square root so gradients stay finite. Pair vectors are `PVec`s of (B, K) components.
"""
from dataclasses import dataclass

import jax
import jax.numpy as jnp

from .pvec import PVec, dot


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Pairs:
    """Neighbour geometry of the B particles i of a block with their K neighbour slots j.

    j    (B, K) neighbour index (padding clipped to a valid index, see `mask`)
    mask (B, K) true for real neighbours
    dr   PVec of (B, K): r_i - r_j (minimum image; arbitrary but finite in padded slots)
    d    (B, K) |r_ij| (beyond the kernel support in padded slots)
    w    (B, K) W(|r_ij|)
    f    (B, K) dW/dr / |r_ij|, the scalar factor of most SPH pair terms
    """

    j: jax.Array
    mask: jax.Array
    dr: PVec
    d: jax.Array
    w: jax.Array
    f: jax.Array

    @property
    def e(self) -> PVec:
        """Unit vectors e_ij = r_ij / |r_ij|."""
        return self.dr / self.d

    @property
    def grad_w(self) -> PVec:
        """Kernel gradient with respect to r_i: dW/dr e_ij."""
        return self.f * self.dr


def take(x, j):
    """x[j] for a 1D array x and indices 0 <= j < len(x): a bare XLA gather (`x[j]` first maps
    negative indices, three more operations per pair and gathered field; 2D step 15 % faster)."""
    dn = jax.lax.GatherDimensionNumbers(offset_dims=(), collapsed_slice_dims=(0,), start_index_map=(0,))
    return jax.lax.gather(x, j[..., None], dn, slice_sizes=(1,), mode=jax.lax.GatherScatterMode.PROMISE_IN_BOUNDS)


def sum_j(x):
    """Sum a pair quantity over the neighbours j, keeping a (B, 1) axis (PVec: per component).

    A PVec's components are summed in one reduction of their stack: XLA's CPU backend makes one
    loop nest per reduction and re-evaluates the pair expression (geometry, kernel, gathers) in
    each, so per-component sums cost a pass over the pairs per component. Stacked, the 2D TGV step
    reads 27 % (standard SPH) and 40 % (TVF) fewer bytes (XLA's cost analysis) and TVF costs about
    what standard SPH does (bench/bench_tvf_cost.py)."""
    if isinstance(x, PVec):
        s = jnp.sum(jnp.stack(x.c, axis=0), axis=-1, keepdims=True)
        return PVec(s[a] for a in range(len(x.c)))
    return jnp.sum(x, axis=-1, keepdims=True)


def pair_geometry(r_own: PVec, r_all: PVec, idx, domain, margin, kernel) -> Pairs:
    """Pairs of the block rows whose positions are `r_own` ((B, 1) components) with their neighbour
    slots `idx` (B, K); `r_all` holds every particle's position ((N,) components).
    `domain.minimum_image(delta, axis, margin)` wraps each component as the neighbour search does."""
    n = r_all.c[0].shape[0]
    mask = idx < n
    j = jnp.where(mask, idx, 0)
    dr = PVec(domain.minimum_image(ri - take(ra, j), a, margin) for a, (ri, ra) in enumerate(zip(r_own.c, r_all.c)))
    far = 2.0 * kernel.cutoff
    d = jnp.sqrt(jnp.where(mask, dot(dr, dr), far * far))
    dw = kernel.dwdr(d)
    return Pairs(j=j, mask=mask, dr=dr, d=d, w=kernel.w(d), f=dw / d)
