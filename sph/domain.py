"""Simulation box with per-dimension periodicity: displacement and shift functions.

Positions live in [0, box). In non-periodic dimensions the neighbour search box is enlarged by a
margin >= cutoff + skin, so the minimum-image convention used by the cell list never connects
particles across a non-periodic boundary.
"""
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np


@dataclass(frozen=True)
class Domain:
    """Box [0, box_d) in each dimension d, periodic where `periodic[d]` is true."""

    box: tuple
    periodic: tuple

    def __post_init__(self):
        if len(self.box) != len(self.periodic):
            raise ValueError(f"domain: box {self.box} and periodic {self.periodic} differ in length")
        if any(b <= 0 for b in self.box):
            raise ValueError(f"domain.box: every side must be positive, got {self.box}")

    @property
    def dim(self) -> int:
        return len(self.box)

    def search_box(self, margin: float) -> np.ndarray:
        """Box used by the neighbour search: the domain, padded by `margin` in non-periodic dims."""
        return np.array([b if p else b + margin for b, p in zip(self.box, self.periodic)], dtype=float)

    def make_displacement(self, margin: float):
        """Return disp(ri, rj) = ri - rj under the minimum-image convention of the search box."""
        side = self.search_box(margin)

        def disp(ri, rj, **unused):
            dr = ri - rj
            s = jnp.asarray(side, dr.dtype)
            return dr - s * jnp.round(dr / s)

        return disp

    def minimum_image(self, delta, axis: int, margin: float):
        """Wrap one component of r_i - r_j into [-side/2, side/2] of the search box (see make_displacement)."""
        side = float(self.search_box(margin)[axis])
        return delta - side * jnp.round(delta * (1.0 / side))

    def shift(self, r, dr):
        """Move positions by dr, wrapping periodic dimensions back into [0, box)."""
        r_new = r + dr
        box = jnp.asarray(self.box, r_new.dtype)
        return jnp.where(np.array(self.periodic), jnp.mod(r_new, box), r_new)
