"""Spatial domain decomposition: D slabs cut along the longest axis of the box (issue 40, item 1).

Each device owns the particles whose coordinate along the cut axis lies in its slab
[k w, (k + 1) w), w = L / D (the outermost slabs of a non-periodic axis also own what lies beyond
the box). It also holds halo copies of the particles of its two neighbour slabs within the halo
width of its faces (cutoff + skin, the reach of the neighbour list), so that every pair of an
owned particle is present on its device, as in the domain decomposition of molecular dynamics
(GROMACS, LAMMPS: "ghost" atoms). A periodic cut axis wraps: slab 0 and slab D-1 are neighbours.

Refusal: a slab narrower than the halo width (a pair would then reach two slabs over); the error
names the largest D that works. Two slabs on a periodic axis (both neighbours the same device) need
no more: a particle within the halo width of both faces is sent once (`sph.parallel.halo.build`).
"""
import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError


@dataclass(frozen=True)
class Decomposition:
    """D slabs along `axis` of a box of `side` (the cut axis' length), `periodic` along it, with a
    halo of `halo` (cutoff + skin) on each face."""

    devices: int
    axis: int
    side: float
    periodic: bool
    halo: float

    def __post_init__(self):
        if not (isinstance(self.devices, int) and not isinstance(self.devices, bool) and self.devices >= 1):
            raise ConfigError(f"devices: must be a whole number >= 1, got {self.devices!r}")
        if not (math.isfinite(self.side) and self.side > 0):
            raise ConfigError(f"decomposition: the cut axis' side must be positive and finite, got {self.side!r}")
        if not (math.isfinite(self.halo) and self.halo > 0):
            raise ConfigError(f"decomposition: the halo width must be positive and finite, got {self.halo!r}")
        if self.devices > 1 and self.width < self.min_width:
            raise ConfigError(
                f"devices: {self.devices} slabs along axis {self.axis} (side {self.side:g}) are {self.width:g} wide, "
                f"narrower than the halo width {self.min_width:g} (cutoff + skin); the largest D that works is "
                f"{self.largest_devices(self.side, self.periodic, self.halo)}")

    @property
    def width(self) -> float:
        """The slab width L / D."""
        return self.side / self.devices

    @property
    def min_width(self) -> float:
        """The narrowest slab that works: the halo width."""
        return self.halo

    @staticmethod
    def largest_devices(side: float, periodic: bool, halo: float) -> int:
        """The largest D whose slabs are wide enough (1 if none is)."""
        return max(1, int(math.floor(side / halo * (1.0 + 1e-12))))

    def slab_of(self, x):
        """Slab index of coordinates `x` along the cut axis (jnp or numpy): floor(x / w), wrapped on a
        periodic axis, clipped to [0, D) on a closed one."""
        xp = _xp(x)
        k = xp.floor(x * (1.0 / self.width)).astype(xp.int32)
        return xp.mod(k, self.devices) if self.periodic else xp.clip(k, 0, self.devices - 1)

    def bounds(self, k):
        """(lo, hi) of slab k along the cut axis (lo -inf / hi +inf at the ends of a closed axis)."""
        lo, hi = k * self.width, (k + 1) * self.width
        if not self.periodic:
            lo = -math.inf if k == 0 else lo
            hi = math.inf if k == self.devices - 1 else hi
        return lo, hi

    def perm(self, shift: int) -> tuple:
        """ppermute pairs (source, destination) sending from slab k to slab k + shift (+-1), wrapped
        on a periodic axis; on a closed one the end slabs send nothing past the box."""
        d = self.devices
        if self.periodic:
            return tuple((k, (k + shift) % d) for k in range(d))
        return tuple((k, k + shift) for k in range(d) if 0 <= k + shift < d)

    def halo_estimate(self, n: int, box) -> float:
        """Surface-to-volume estimate of the halo particles of one device: n_dev particles in a slab
        of width w, two faces (one on a closed axis' end slab) of depth `halo`: n_dev * 2 halo / w."""
        faces = 2 if (self.periodic or self.devices > 2) else 1
        return n / self.devices * faces * self.halo / self.width if self.devices > 1 else 0.0


def _xp(x):
    if isinstance(x, np.ndarray) or np.isscalar(x):
        return np
    import jax.numpy as jnp

    return jnp


def decompose(domain, halo: float, devices: int, axis=None) -> Decomposition:
    """The slabs of `domain` (sph.domain.Domain) for `devices` devices: cut along the longest axis
    (the first of equal ones), or `axis`; `halo` = cutoff + skin."""
    box = tuple(float(b) for b in domain.box)
    if axis is None:
        axis = int(np.argmax(box))
    if not (0 <= axis < len(box)):
        raise ConfigError(f"decomposition.axis: {axis!r} is not an axis of the {len(box)}D domain")
    return Decomposition(devices=devices, axis=axis, side=box[axis], periodic=bool(domain.periodic[axis]),
                         halo=float(halo))
