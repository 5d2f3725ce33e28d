"""Neighbour search behind one interface: this solver's sort-based cell list or jax-md's (reference).

Both give jax-md's Dense format, (N, K) idx padded with N, holding all pairs within cutoff + skin;
`update` rebuilds the list only when some particle has moved more than skin / 2 since the last
build (the Verlet-skin threshold), so most steps reuse it. `update` never changes the capacity K;
when more than K neighbours (or cell-list slots) are needed it raises `did_buffer_overflow`, and the
caller must re-`allocate` outside `jit` (see `sph.rollout`).

backend "cell_sort" (the default, `numerics.neighbor_search`): `sph.cell_list` (argsort by cell,
per-cell-offset gathers with a running compaction; memory O(N K)). backend "jax_md":
`jax_md.partition.neighbor_list`, kept as the reference implementation the cell list is tested
against (tests/core/test_cell_list.py: identical pair sets). In 2D the two take the same time per step
(TGV dx 0.02; dx 0.01: jax-md 1.1x); in 3D jax-md's rebuild takes 5x as long and 14x the memory
(16^3: 150 against 32 ms, 0.22 against 0.016 GB; bench/bench_neighbors.py).
"""
from dataclasses import dataclass
from typing import Any

import jax

from . import cell_list

BACKENDS = ("cell_sort", "jax_md")


@dataclass(frozen=True, eq=False)
class NeighborSearch:
    """allocate(r) builds a list with fresh capacity (not jittable); update(r, nbrs) is jittable.
    Lists carry idx, reference_position, did_buffer_overflow, max_occupancy, cell_list_capacity."""

    impl: Any
    cutoff: float
    skin: float
    backend: str = "cell_sort"

    def allocate(self, r, extra_capacity: int = 0):
        return self.impl.allocate(jax.lax.stop_gradient(r), extra_capacity=extra_capacity)

    def update(self, r, nbrs):
        return self.impl.update(jax.lax.stop_gradient(r), nbrs)


def _jax_md_search(domain, cutoff, skin, capacity_multiplier):
    from jax_md import partition

    margin = cutoff + skin
    return partition.neighbor_list(
        domain.make_displacement(margin),
        domain.search_box(margin),
        r_cutoff=cutoff,
        dr_threshold=skin,
        capacity_multiplier=capacity_multiplier,
        format=partition.NeighborListFormat.Dense,
    )


def make_neighbor_search(domain, cutoff: float, skin: float, capacity_multiplier: float = 1.25,
                         backend: str = "cell_sort") -> NeighborSearch:
    """Cell-list neighbour search over `domain` for pairs closer than `cutoff` (+ `skin` of slack).
    `backend`: "cell_sort" (sph.cell_list) or "jax_md" (jax-md's cell list)."""
    if backend == "cell_sort":
        impl = cell_list.make_cell_list(domain, cutoff, skin, capacity_multiplier)
    elif backend == "jax_md":
        impl = _jax_md_search(domain, cutoff, skin, capacity_multiplier)
    else:
        raise ValueError(f"numerics.neighbor_search: {backend!r} is not one of {list(BACKENDS)}")
    return NeighborSearch(impl=impl, cutoff=float(cutoff), skin=float(skin), backend=backend)
