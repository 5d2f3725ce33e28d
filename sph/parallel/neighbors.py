"""The neighbour list of one device: `sph.cell_list` over its owned and halo particles, padding excluded.

A device's arrays have fixed capacities (owned slots, halo slots), so some rows are padding. The
search takes positions with padding rows set to NaN (`search_positions`): those rows are sorted into
a cell past the last one, so they are nobody's candidates and fill no cell slot, and as rows
their distances are NaN, so they list no neighbour. Everything else is `sph.cell_list.CellListSearch`
unchanged (the same cells, offsets, capacities C and K and the same overflow flag). The sharded step
builds it whenever it rebuilds the halo lists and migrates (the rows of a device change then), by the
Verlet criterion over all devices (`sph.parallel.driver`).
"""
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from ..cell_list import CellListSearch


@dataclass(frozen=True)
class MaskedCellList(CellListSearch):
    """`CellListSearch` whose rows with non-finite positions are padding (module docstring)."""

    def _sort(self, r):
        n = r.shape[0]
        valid = jnp.all(jnp.isfinite(r), axis=1)
        coords = self._cell_coords(jnp.where(valid[:, None], r, 0.0))
        n_total = int(np.prod(self.n_cells))
        cid = jnp.where(valid, self._linear(coords), n_total)          # padding: past the last cell
        order = jnp.argsort(cid, stable=True).astype(jnp.int32)
        cid_sorted = cid[order]
        cells = jnp.arange(n_total, dtype=jnp.int32)
        start = jnp.searchsorted(cid_sorted, cells, side="left").astype(jnp.int32)
        count = jnp.searchsorted(cid_sorted, cells, side="right").astype(jnp.int32) - start
        pad = jnp.zeros((1, self.dim), r.dtype)
        rs_t = jnp.concatenate([r[order], pad]).T
        return order, rs_t, coords[order], start, count, n

    def build(self, r, valid, C: int, K: int):
        """The list (sph.cell_list.CellNeighborList, padded with len(r)) of the rows `valid` at r,
        with cell capacity C and K slots (static); jittable."""
        return self._build(search_positions(r, valid), C, K)

    def cell_need(self, r, valid):
        """The largest cell count of the valid rows (the cell capacity C a list needs)."""
        return self._sort(search_positions(r, valid))[4].max()

    def slot_need(self, r, valid, C: int):
        """The largest neighbour count of the valid rows, with cell capacity C (static)."""
        return jnp.max(self._scan_offsets(search_positions(r, valid), C, 0)[1])


def search_positions(r, valid):
    """Positions for the search: NaN on padding rows (never a neighbour), without a gradient."""
    return jnp.where(valid[:, None], jax.lax.stop_gradient(r), jnp.nan)


def masked_search(search: CellListSearch) -> MaskedCellList:
    """The masked search over the same box, radius and capacity multiplier as `search`."""
    return MaskedCellList(side=search.side, cutoff=search.cutoff, skin=search.skin,
                          capacity_multiplier=search.capacity_multiplier)
