"""The scene of the inverse problem (JAX-SPH, Toshev et al. 2024, Sec. 4.1, Fig. 2): a square block
("cube") of water falling in a closed box under gravity.

Box interior [0, L] x [0, L] (L = 1 in the paper), framed by `layers` layers of no-slip wall particles
(Adami 2012) built with `sph.lattice.wall_layers`, as `sph.cases.tank` does; the whole scene is
shifted by `layers * dx` so that the walls lie inside the simulation box [0, L + 2 layers dx).
The block fills [origin, origin + size]^2 of the interior with a cell-centred lattice (size 0.3 at
dx = 0.05: 6 x 6 = 36 particles) and starts with a uniform velocity u0 (the paper: (0, -0.5)).

All positions handed to or returned by this module are in *scene* coordinates (walls included);
`offset(dx, layers)` converts interior coordinates (the paper's) to scene coordinates.
"""
import numpy as np

from sph.config import Effects, Material
from sph.domain import Domain
from sph.lattice import cartesian, wall_layers
from sph.scene import Scene
from sph.state import FLUID, WALL


def offset(dx: float, layers: int) -> float:
    """Shift between interior coordinates ([0, L]^2, the paper's) and scene coordinates."""
    return layers * dx


def block(origin, size: float, dx: float, layers: int) -> np.ndarray:
    """Cell-centred lattice of the block [origin, origin + size]^2 (interior coordinates), returned in
    scene coordinates: (n_side^2, 2), n_side = size / dx."""
    lo = np.asarray(origin, float) + offset(dx, layers)
    return cartesian(lo, lo + size, dx)


def scene(dx: float, material: Material, effects: Effects, fluid: np.ndarray, u0, box_size: float = 1.0,
          layers: int = 3, name: str = "cube_fall") -> Scene:
    """Fluid particles at `fluid` (scene coordinates, (n, 2)) with velocity `u0`, inside the walled box."""
    off = offset(dx, layers)
    lo, hi = np.array([off, off]), np.array([off + box_size, off + box_size])
    wall, normal = wall_layers(lo, hi, dx, layers)
    fluid = np.asarray(fluid, float)
    r = np.concatenate([fluid, wall])
    tag = np.concatenate([np.full(len(fluid), FLUID), np.full(len(wall), WALL)]).astype(np.int32)
    u = np.zeros_like(r)
    u[: len(fluid)] = np.asarray(u0, float)
    nrm = np.concatenate([np.zeros_like(fluid), normal])
    side = box_size + 2 * off
    return Scene(name=name, dx=dx, domain=Domain(box=(side, side), periodic=(False, False)), material=material,
                 effects=effects, r=r, u=u, tag=tag, normal=nrm)


def interior_bounds(dx: float, layers: int, box_size: float = 1.0, margin: float = 0.0):
    """(lo, hi) of the fluid region in scene coordinates, shrunk by `margin` on every side."""
    off = offset(dx, layers)
    return off + margin, off + box_size - margin
