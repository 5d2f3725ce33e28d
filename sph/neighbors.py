"""Neighbour search through jax-md cell lists, in jax-md's Dense format (N, K) padded with N.

The list holds all pairs within cutoff + skin and is rebuilt by `update` only when some particle has
moved more than skin / 2 since the last build (jax-md's displacement threshold), so most steps reuse
it. `update` never changes the capacity K; when more than K neighbours (or cell-list slots) are
needed it raises `did_buffer_overflow`, and the caller must re-`allocate` outside `jit`
(see `sph.rollout`).
"""
from dataclasses import dataclass

import jax
from jax_md import partition


@dataclass(frozen=True, eq=False)
class NeighborSearch:
    """allocate(r) builds a list with fresh capacity (not jittable); update(r, nbrs) is jittable."""

    fns: partition.NeighborListFns
    cutoff: float
    skin: float

    def allocate(self, r, extra_capacity: int = 0):
        return self.fns.allocate(jax.lax.stop_gradient(r), extra_capacity=extra_capacity)

    def update(self, r, nbrs):
        return self.fns.update(jax.lax.stop_gradient(r), nbrs)


def make_neighbor_search(domain, cutoff: float, skin: float, capacity_multiplier: float = 1.25) -> NeighborSearch:
    """Cell-list neighbour search over `domain` for pairs closer than `cutoff` (+ `skin` of slack)."""
    margin = cutoff + skin
    fns = partition.neighbor_list(
        domain.make_displacement(margin),
        domain.search_box(margin),
        r_cutoff=cutoff,
        dr_threshold=skin,
        capacity_multiplier=capacity_multiplier,
        format=partition.NeighborListFormat.Dense,
    )
    return NeighborSearch(fns=fns, cutoff=cutoff, skin=skin)
