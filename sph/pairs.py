"""Pair geometry over a dense neighbour list: the one place where neighbour data is gathered.

With jax-md's Dense format, `idx` has shape (N, K) and is padded with N. Every pairwise sum is then a
gather plus a reduction over the last axis, which needs no scatter-add. Vector pair quantities are
stored component-major, (dim, N, K), so every component is a contiguous (N, K) slab that XLA
vectorizes well (twice as fast on CPU as an (N, K, dim) layout). Padded slots get a distance beyond
the kernel support, so W = dW/dr = 0 there and no masking is needed in the physics; distances use a
safe square root so gradients stay finite.
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
    dr   (dim, N, K) r_i - r_j (minimum image; arbitrary but finite in padded slots)
    d    (N, K) |r_ij| (beyond the kernel support in padded slots)
    w    (N, K) W(|r_ij|)
    f    (N, K) dW/dr / |r_ij|, the scalar factor of most SPH pair terms
    """

    j: jax.Array
    mask: jax.Array
    dr: jax.Array
    d: jax.Array
    w: jax.Array
    f: jax.Array

    def gather(self, x):
        """x_j of a per-particle scalar for every pair: (N,) -> (N, K)."""
        return x[self.j]

    def gather_vec(self, x):
        """x_j of a per-particle vector, component-major: (N, dim) -> (dim, N, K)."""
        x_t = x.T
        return jnp.stack([x_t[a][self.j] for a in range(x_t.shape[0])])

    @staticmethod
    def own_vec(x):
        """x_i of a per-particle vector broadcast against pairs: (N, dim) -> (dim, N, 1)."""
        return x.T[:, :, None]

    @staticmethod
    def sum_vec(x):
        """Sum a component-major pair vector over neighbours: (dim, N, K) -> (N, dim)."""
        return jnp.sum(x, axis=-1).T

    @property
    def e(self):
        """Unit vectors e_ij = r_ij / |r_ij| (dim, N, K)."""
        return self.dr / self.d

    @property
    def grad_w(self):
        """Kernel gradient with respect to r_i: dW/dr e_ij (dim, N, K)."""
        return self.f * self.dr


def cdot(a, b):
    """Component-wise dot product of two component-major pair vectors: (dim, N, K) -> (N, K).

    Written as an explicit sum over the few components: XLA fuses it, whereas a reduction over the
    leading axis is lowered to a separate, several times slower reduce on CPU.
    """
    out = a[0] * b[0]
    for k in range(1, a.shape[0]):
        out = out + a[k] * b[k]
    return out


def pair_geometry(r, idx, domain, margin, kernel) -> Pairs:
    """Gather positions over the neighbour list and evaluate the kernel for every pair.

    `domain.minimum_image(delta, axis, margin)` wraps each component as the neighbour search does.
    """
    n = r.shape[0]
    mask = idx < n
    j = jnp.where(mask, idx, 0)
    r_t = r.T
    dr = jnp.stack([domain.minimum_image(r_t[a][:, None] - r_t[a][j], a, margin) for a in range(r.shape[1])])
    far = 2.0 * kernel.cutoff
    d = jnp.sqrt(jnp.where(mask, cdot(dr, dr), far * far))
    dw = kernel.dwdr(d)
    return Pairs(j=j, mask=mask, dr=dr, d=d, w=kernel.w(d), f=dw / d)
