"""Sort-based cell list with a Verlet skin: the neighbour search built for this solver.

Algorithm (the linked-cell method of Hockney & Eastwood, in the sorted "cell index + offset" form
used on GPUs, e.g. Green 2010, "Particle simulation using CUDA"):

1. Bin: the search box (the domain, padded by margin = cutoff + skin in non-periodic dimensions, see
   `sph.domain`) is cut into n_d = floor(side_d / margin) cells per dimension, so a cell side is at
   least the search radius and every pair closer than it lies in the same or an adjacent cell
   (3^dim cells). Cell indices wrap in every dimension, matching the minimum-image convention of
   the search box that the pair geometry also uses. A dimension too short for three cells gets one
   cell (so no neighbour cell is visited twice).
2. Sort: particles are ordered by linear cell id with a stable `argsort`; a cell's particles are then
   contiguous, from start[c] (`searchsorted`) for count[c] entries.
3. Gather and prune: for each of the 3^dim cell offsets in turn (a `lax.scan`), every particle takes
   the first C (cell capacity) sorted particles of the offset cell as candidates, keeps those closer
   than the search radius (minimum image) and appends them to its K neighbour slots with a running
   compaction (slot = neighbours so far + cumulative count). Only (N, C) candidates exist at a time,
   never the (N, 3^dim C) block a one-shot dense prune needs.
4. Verlet skin (Verlet 1967): the list holds every pair within cutoff + skin, so it stays valid until
   some particle has moved more than skin / 2 since the build; `update` rebuilds only then
   (`lax.cond`) and otherwise returns the list unchanged.

The result uses jax-md's Dense format, idx (N, K) padded with N, so `sph.pairs` works unchanged.
Capacities are static: K and C are chosen by `allocate` (not jittable) from the actual largest
neighbour and cell counts times `capacity_multiplier` (plus `extra_capacity`), and a jitted
`update` that needs more raises `did_buffer_overflow` (never a silently truncated list); the caller
re-allocates outside `jit` (`sph.rollout`). Positions enter with `stop_gradient`: the list is
piecewise constant in r, so differentiated rollouts see no derivative through it.
"""
import itertools
import math
from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class CellNeighborList:
    """A Dense neighbour list built by the cell list.

    idx                 (N, K) int32 neighbour indices j != i with |r_ij| < cutoff + skin, padded with N
    reference_position  (N, dim) positions at the last build (the Verlet-skin reference)
    did_buffer_overflow () bool, true if the last build needed more than K slots or C cell slots
    max_occupancy       K, neighbour slots per particle (static)
    cell_list_capacity  C, particle slots per cell (static)
    """

    idx: jax.Array
    reference_position: jax.Array
    did_buffer_overflow: jax.Array
    max_occupancy: int = field(metadata=dict(static=True))
    cell_list_capacity: int = field(metadata=dict(static=True))


@dataclass(frozen=True)
class CellListSearch:
    """Cell-list neighbour search over a box of sides `side` (the search box), wrapping in every
    dimension. allocate(r) is not jittable (it sizes the capacities); update(r, nbrs) is.
    Compared and hashed by value, so that the jitted functions of `allocate` (which take the search
    as a static argument) are compiled once per search, not once per solver built."""

    side: tuple
    cutoff: float
    skin: float
    capacity_multiplier: float = 1.25
    n_cells: tuple = field(init=False)

    def __post_init__(self):
        radius = self.radius
        if not radius > 0:
            raise ValueError(f"cell list: the search radius cutoff + skin must be positive, got {radius}")
        # floor with a hair of slack, so a box that is an exact multiple of the radius does not get
        # cells a rounding error smaller than it
        n = [int(math.floor(s / radius * (1.0 - 1e-12))) for s in self.side]
        n = [c if c >= 3 else 1 for c in n]
        object.__setattr__(self, "n_cells", tuple(n))

    @property
    def radius(self) -> float:
        return float(self.cutoff + self.skin)

    @property
    def dim(self) -> int:
        return len(self.side)

    @property
    def cell_size(self) -> np.ndarray:
        return np.asarray(self.side, float) / np.asarray(self.n_cells)

    def offsets(self) -> np.ndarray:
        """The 3^dim cell offsets (only 0 in dimensions with a single cell): (n_offsets, dim) int32."""
        per_dim = [(-1, 0, 1) if c >= 3 else (0,) for c in self.n_cells]
        return np.array(list(itertools.product(*per_dim)), dtype=np.int32)

    # -- geometry ---------------------------------------------------------------------------------

    def _cell_coords(self, r):
        """Integer cell coordinates (N, dim), wrapped into [0, n_d).

        r / cell is truncated toward zero, as jax-md's cell list does, not floored: the two differ
        only for negative coordinates, i.e. outside the search box (a particle that left a
        non-periodic side, which the step guard refuses; periodic positions are wrapped into the
        box), and there they put a particle in the same cell as jax-md, so that a rollout continued
        past such a step (scan_rollout only flags it) overflows exactly when jax-md's would."""
        inv = jnp.asarray(1.0 / self.cell_size, r.dtype)
        c = (r * inv).astype(jnp.int32)
        return jnp.mod(c, jnp.asarray(self.n_cells, jnp.int32))

    def _linear(self, coords):
        """Row-major linear cell id of integer coordinates (..., dim)."""
        cid = coords[..., 0]
        for d in range(1, self.dim):
            cid = cid * self.n_cells[d] + coords[..., d]
        return cid

    def _minimum_image(self, delta, axis):
        side = float(self.side[axis])
        return delta - side * jnp.round(delta * (1.0 / side))

    def _max_displacement_sq(self, r, r_ref):
        d2 = 0.0
        for a in range(self.dim):
            d2 = d2 + self._minimum_image(r[:, a] - r_ref[:, a], a) ** 2
        return jnp.max(d2)

    # -- build ------------------------------------------------------------------------------------

    def _sort(self, r):
        """Particles sorted by cell: (order, sorted positions (dim, N + 1) padded, sorted cell
        coordinates (N, dim), cell start (n_cells,), cell count (n_cells,))."""
        n = r.shape[0]
        coords = self._cell_coords(r)
        cid = self._linear(coords)
        order = jnp.argsort(cid, stable=True).astype(jnp.int32)
        cid_sorted = cid[order]
        cells = jnp.arange(int(np.prod(self.n_cells)), dtype=jnp.int32)
        start = jnp.searchsorted(cid_sorted, cells, side="left").astype(jnp.int32)
        count = jnp.searchsorted(cid_sorted, cells, side="right").astype(jnp.int32) - start
        pad = jnp.zeros((1, self.dim), r.dtype)  # the padding slot N (never a hit: masked)
        rs_t = jnp.concatenate([r[order], pad]).T
        return order, rs_t, coords[order], start, count, n

    def _scan_offsets(self, r, C, K):
        """Visit the 3^dim neighbour cells; with K > 0 fill the (N, K) sorted-space slots.

        Returns (slots (N, K) of sorted indices padded with N, or None for K = 0; number of
        neighbours of every sorted particle (N,); largest cell count; order)."""
        order, rs_t, coords_s, start, count, n = self._sort(r)
        r2 = jnp.asarray(self.radius**2, r.dtype)
        slot = jnp.arange(C, dtype=jnp.int32)
        me = jnp.arange(n, dtype=jnp.int32)
        n_cells = jnp.asarray(self.n_cells, jnp.int32)

        def visit(carry, off):
            nbr, filled = carry
            cell = self._linear(jnp.mod(coords_s + off, n_cells))
            valid = slot[None, :] < count[cell][:, None]                           # (N, C)
            cand = jnp.where(valid, start[cell][:, None] + slot[None, :], n)         # sorted index
            d2 = 0.0
            for a in range(self.dim):
                d2 = d2 + self._minimum_image(rs_t[a, :n, None] - rs_t[a][cand], a) ** 2
            hit = valid & (d2 < r2) & (cand != me[:, None])
            if K:
                # running compaction: the k-th hit in this cell goes to slot filled + k - 1; misses
                # and slots beyond K go to column K and are dropped (the overflow is counted in filled)
                pos = jnp.where(hit, filled[:, None] + _hits_before(hit), K)
                nbr = nbr.at[me[:, None], pos].set(cand, mode="drop", unique_indices=True)
            filled = filled + jnp.sum(hit, axis=1, dtype=jnp.int32)
            return (nbr, filled), None

        nbr0 = jnp.full((n, K), n, jnp.int32)
        (nbr, filled), _ = jax.lax.scan(visit, (nbr0, jnp.zeros(n, jnp.int32)), jnp.asarray(self.offsets()))
        return (nbr if K else None), filled, jnp.max(count), order

    def _build(self, r, C: int, K: int) -> CellNeighborList:
        """Build the list at r with cell capacity C and K slots (jittable, static C and K)."""
        n = r.shape[0]
        nbr, filled, max_count, order = self._scan_offsets(r, C, K)
        # back from sorted to original particle numbering: row order[p] holds order[nbr[p]]
        order_pad = jnp.concatenate([order, jnp.full((1,), n, jnp.int32)])
        rank = jnp.zeros(n, jnp.int32).at[order].set(jnp.arange(n, dtype=jnp.int32), unique_indices=True)
        idx = order_pad[nbr[rank]]  # a gather of rows: several times faster than scattering them
        overflow = (jnp.max(filled) > K) | (max_count > C)
        return CellNeighborList(idx=idx, reference_position=r, did_buffer_overflow=overflow,
                                max_occupancy=K, cell_list_capacity=C)

    # -- public -----------------------------------------------------------------------------------

    def allocate(self, r, extra_capacity: int = 0) -> CellNeighborList:
        """Build a list at r with fresh capacities: C = largest cell count and K = largest neighbour
        count, each times `capacity_multiplier`, plus `extra_capacity` (not jittable)."""
        r = jax.lax.stop_gradient(jnp.asarray(r))
        max_count = int(_max_cell_count(self, r))
        c_need = max(max_count, 1)
        filled = int(_count_neighbors(self, r, c_need))
        C = int(c_need * self.capacity_multiplier + extra_capacity)
        K = max(int(filled * self.capacity_multiplier + extra_capacity), 1)
        return _build_jit(self, r, C, K)

    def update(self, r, nbrs: CellNeighborList) -> CellNeighborList:
        """The list at r (jittable): rebuilt with the same capacities if some particle moved more than
        skin / 2 (minimum image) since the last build, otherwise `nbrs` unchanged."""
        r = jax.lax.stop_gradient(r)
        moved = self._max_displacement_sq(r, nbrs.reference_position) > (0.5 * self.skin) ** 2
        return jax.lax.cond(moved, lambda: self._build(r, nbrs.cell_list_capacity, nbrs.max_occupancy),
                            lambda: nbrs)


def _hits_before(hit):
    """Number of true entries before each one along the last axis of a boolean (rows, C) array: the
    exclusive prefix sum, from bit counts. The hits of 32 consecutive slots are packed into one
    uint32 word; the count before slot c is the population count of its word's lower bits plus the
    counts of the words before. Elementwise operations and one short reduction, which XLA fuses,
    where `cumsum` (a reduce-window) made up two thirds of a list build on the CPU."""
    rows, c = hit.shape
    w = -(-c // 32)
    shift = (jnp.arange(w * 32, dtype=jnp.uint32) % 32).reshape(w, 32)
    lower = (jnp.uint32(1) << shift) - jnp.uint32(1)                                # bits below each slot
    bits = jnp.pad(hit, ((0, 0), (0, w * 32 - c))).reshape(rows, w, 32).astype(jnp.uint32) << shift
    words = jnp.sum(bits, axis=2, dtype=jnp.uint32)                                # distinct bits: sum = or
    per_word = jax.lax.population_count(words).astype(jnp.int32)
    earlier = [jnp.zeros((rows,), jnp.int32)]
    for k in range(1, w):
        earlier.append(earlier[-1] + per_word[:, k - 1])
    before = jax.lax.population_count(words[:, :, None] & lower).astype(jnp.int32) + jnp.stack(earlier, 1)[:, :, None]
    return before.reshape(rows, w * 32)[:, :c]


# jitted entry points of `allocate`; the search is a static argument (hashed by value)
def _max_cell_count_impl(search, r):
    return search._sort(r)[4].max()


def _count_neighbors_impl(search, r, C):
    return jnp.max(search._scan_offsets(r, C, 0)[1])


_max_cell_count = jax.jit(_max_cell_count_impl, static_argnums=0)
_count_neighbors = jax.jit(_count_neighbors_impl, static_argnums=(0, 2))
_build_jit = jax.jit(lambda search, r, C, K: search._build(r, C, K), static_argnums=(0, 2, 3))


def make_cell_list(domain, cutoff: float, skin: float, capacity_multiplier: float = 1.25) -> CellListSearch:
    """Cell-list search over `domain` (sph.domain.Domain) for pairs closer than cutoff + skin; the
    search box is padded by the margin cutoff + skin in non-periodic dimensions."""
    side = tuple(float(s) for s in domain.search_box(cutoff + skin))
    return CellListSearch(side=side, cutoff=float(cutoff), skin=float(skin),
                          capacity_multiplier=float(capacity_multiplier))
