"""2D lid-driven cavity (Ghia, Ghia & Shin 1982): unit square, lid (top wall) moving at U in +x.

The fluid fills [0, 1]^2 shifted by `layers * dx` so that the wall layers lie inside the box
[0, 1 + 2 layers dx). Re = U L / nu; u_ref = U. The centreline profiles are compared with Ghia's
Table I (u at x = 0.5) and Table II (v at y = 0.5).
"""
import numpy as np

from ..config import Effects, Material
from ..domain import Domain
from ..lattice import cartesian, check_run_size, count, wall_layers
from ..scene import Scene
from ..state import FLUID, MOVING_WALL, WALL


def scene(dx: float, material: Material, effects: Effects, layers: int = 3, lid_velocity: float = 1.0,
          name: str = "ldc2d") -> Scene:
    off = layers * dx
    lo, hi = np.array([off, off]), np.array([off + 1.0, off + 1.0])
    check_run_size(count(lo - off, hi + off, dx), dx, f"scene {name}")
    fluid = cartesian(lo, hi, dx)
    wall, normal = wall_layers(lo, hi, dx, layers)
    lid = wall[:, 1] > hi[1]
    r = np.concatenate([fluid, wall])
    tag = np.concatenate([np.full(len(fluid), FLUID), np.where(lid, MOVING_WALL, WALL)]).astype(np.int32)
    u = np.zeros_like(r)
    u[len(fluid):][lid, 0] = lid_velocity
    nrm = np.concatenate([np.zeros_like(fluid), normal])
    side = 1.0 + 2 * off
    return Scene(name=name, dx=dx, domain=Domain(box=(side, side), periodic=(False, False)), material=material,
                 effects=effects, r=r, u=u, tag=tag, normal=nrm)


def offset(dx: float, layers: int = 3) -> float:
    """Shift between cavity coordinates (Ghia's [0, 1]^2) and scene coordinates."""
    return layers * dx
