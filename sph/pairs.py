"""Pair geometry over a dense neighbour list: the one place where neighbour data is gathered.

With jax-md's Dense format, `idx` has shape (N, K) and is padded with N. Every pairwise sum is then a
gather plus a reduction over axis 1, which needs no scatter-add and vectorizes well on CPU. Padded
slots get a distance beyond the kernel support, so W = dW/dr = 0 there and no masking is needed in
the physics; distances are computed with a safe square root so gradients stay finite.
"""
from dataclasses import dataclass

import jax
import jax.numpy as jnp


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Pairs:
    """Neighbour geometry of every particle i with its K neighbour slots j.

    j    (N, K) neighbour index (padding clipped to a valid index, see `mask`)
    mask (N, K) true for real neighbours
    dr   (N, K, dim) r_i - r_j (minimum image; arbitrary but finite in padded slots)
    d    (N, K) |r_ij| (beyond the kernel support in padded slots)
    w    (N, K) W(|r_ij|)
    dw   (N, K) dW/dr(|r_ij|)
    f    (N, K) dW/dr / |r_ij|, the scalar factor of most SPH pair terms
    """

    j: jax.Array
    mask: jax.Array
    dr: jax.Array
    d: jax.Array
    w: jax.Array
    dw: jax.Array
    f: jax.Array

    def gather(self, x):
        """x_j for every pair: (N, ...) -> (N, K, ...)."""
        return x[self.j]

    @property
    def e(self):
        """Unit vectors e_ij = r_ij / |r_ij| (N, K, dim)."""
        return self.dr / self.d[..., None]

    @property
    def grad_w(self):
        """Kernel gradient with respect to r_i: dW/dr e_ij (N, K, dim)."""
        return self.f[..., None] * self.dr


def pair_geometry(r, idx, displacement, kernel) -> Pairs:
    """Gather positions over the neighbour list and evaluate the kernel for every pair."""
    n = r.shape[0]
    mask = idx < n
    j = jnp.where(mask, idx, 0)
    dr = jax.vmap(jax.vmap(displacement, (None, 0)), (0, 0))(r, r[j])
    far = 2.0 * kernel.cutoff
    d = jnp.sqrt(jnp.where(mask, jnp.sum(dr * dr, axis=-1), far * far))
    dw = kernel.dwdr(d)
    return Pairs(j=j, mask=mask, dr=dr, d=d, w=kernel.w(d), dw=dw, f=dw / d)
