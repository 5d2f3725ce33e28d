"""Vectors of pair (or per-particle) quantities, held as their `dim` separate components.

A pair vector such as r_ij or u_i - u_j is a tuple of `dim` arrays of shape (B, K) (a block of B
particles times K neighbour slots); a particle's own vector broadcast against its pairs is a tuple of
(B, 1) arrays. Kept apart, each component is a contiguous scalar slab that XLA's CPU backend fuses
and vectorizes like a hand-written loop (a stacked (dim, B, K) array inside a block is ~2x slower).
Arithmetic is component-wise; `dot` is the explicit sum over the few components.
"""
import jax
import jax.numpy as jnp


@jax.tree_util.register_pytree_node_class
class PVec:
    """A `dim`-component vector whose components are arrays of one shape."""

    __slots__ = ("c",)

    def __init__(self, components):
        self.c = tuple(components)

    def tree_flatten(self):
        return self.c, None

    @classmethod
    def tree_unflatten(cls, _, children):
        return cls(children)

    def __len__(self):
        return len(self.c)

    def _map(self, other, op):
        if isinstance(other, PVec):
            return PVec(op(a, b) for a, b in zip(self.c, other.c))
        return PVec(op(a, other) for a in self.c)

    def __add__(self, other):
        return self._map(other, lambda a, b: a + b)

    def __sub__(self, other):
        return self._map(other, lambda a, b: a - b)

    def __mul__(self, other):
        return self._map(other, lambda a, b: a * b)

    def __truediv__(self, other):
        return self._map(other, lambda a, b: a / b)

    def __radd__(self, other):
        return self._map(other, lambda a, b: b + a)

    def __rsub__(self, other):
        return self._map(other, lambda a, b: b - a)

    def __rmul__(self, other):
        return self._map(other, lambda a, b: b * a)

    def __neg__(self):
        return PVec(-a for a in self.c)

    def stack(self):
        """The components side by side along a new last axis: (..., 1) components -> (..., dim)."""
        return jnp.concatenate(self.c, axis=-1) if self.c[0].shape[-1:] == (1,) else jnp.stack(self.c, axis=-1)


def dot(a: PVec, b: PVec):
    """Component-wise dot product a . b, summed in component order."""
    out = a.c[0] * b.c[0]
    for x, y in zip(a.c[1:], b.c[1:]):
        out = out + x * y
    return out


def where(cond, a: PVec, b: PVec) -> PVec:
    """Component-wise jnp.where with one condition for every component."""
    return PVec(jnp.where(cond, x, y) for x, y in zip(a.c, b.c))
