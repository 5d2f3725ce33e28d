"""2D lid-driven cavity (Ghia, Ghia & Shin 1982): unit square, lid (top wall) moving at U in +x.

The fluid fills [0, 1]^2 shifted by `layers * dx` so that the wall layers lie inside the box
[0, 1 + 2 layers dx). Re = U L / nu; u_ref = U. The centreline profiles are compared with Ghia's
Table I (u at x = 0.5) and Table II (v at y = 0.5): sph.cases.ldc_reference (apart, so that editing
a comparison re-runs nothing).

The validated set-up (experiments/ldc2d, JAX-SPH Figs. 6-7): the lid spanning the cavity width only
(`lid_corners="fixed"`), NUMERICS with each method's overrides (`numerics(method)`), the Effects of
METHODS; `setup` gives both:

    scene, numerics = ldc.setup(dx=0.02, re=100, method="tvf")
    solver = sph.build_solver(scene, numerics)
"""
import dataclasses

import numpy as np

from ..config import Effects, Material, Numerics
from ..domain import Domain
from ..errors import require
from ..lattice import cartesian, check_run_size, count, wall_layers
from ..scene import Scene
from ..state import FLUID, MOVING_WALL, WALL

LID_CORNERS = ("moving", "fixed")
"""`moving`: the top wall layers move over their full width, the corner blocks beyond the side walls
included (JAX-SPH). `fixed`: those corner blocks are fixed walls, so the lid spans exactly the cavity
width, as in Ghia's problem. A moving corner block has diagonal wall normals and a velocity with a
component along them, which the one-sided Riemann wall reads as a wall receding from the fluid: at the
downstream corner it sucks fluid particles into the wall (Riemann SPH at dx = 0.02 blows up at t = 0.79)."""

NUMERICS = Numerics(kernel="quintic", h_factor=1.0, cfl=0.25, c_ref_factor=10.0, dtype="float64")
"""The numerics of the validated runs (experiments/ldc2d/config.yaml, profile paper), before the
overrides of each method (METHOD_NUMERICS)."""

METHODS = {
    "sph": Effects(walls="no_slip"),
    "tvf": Effects(tvf=True, walls="no_slip"),
    "riemann": Effects(riemann=True, density_evolution=True, density_reinit_every=20, walls="no_slip"),
}
"""Standard SPH, transport-velocity SPH and Riemann SPH with one-sided Riemann walls: their Effects.
Riemann SPH re-initializes the evolved density (Shepard sum, walls included) every 20 steps: without
it particles creep into the walls at the lid corners (t ~ 1-2 at dx 0.02; experiments/ldc2d/README)."""

METHOD_NUMERICS = {"sph": {"p_bg_factor": 0.01}}
"""Overrides of NUMERICS per method: standard SPH with JAX-SPH's EoS background pressure 0.01 p_ref."""

GHIA_RE = (100, 400, 1000, 3200, 5000, 7500, 10000)
"""The Reynolds numbers of Ghia's tables."""


def numerics(method: str) -> Numerics:
    """NUMERICS with the overrides of `method` (one of METHODS)."""
    require(method in METHODS, "method", f"{method!r} is not one of {list(METHODS)}")
    return dataclasses.replace(NUMERICS, **METHOD_NUMERICS.get(method, {}))


def material(re: float, lid_velocity: float = 1.0, rho_ref: float = 1.0) -> Material:
    """The fluid of Reynolds number re = rho_ref U L / eta (L = 1, U the lid speed = u_ref)."""
    return Material(rho_ref=rho_ref, eta=rho_ref * lid_velocity / re, u_ref=lid_velocity)


def scene(dx: float, material: Material, effects: Effects, layers: int = 3, lid_velocity: float = 1.0,
          name: str = "ldc2d", lid_corners: str = "moving") -> Scene:
    """The cavity at spacing dx; `lid_corners` (LID_CORNERS): `fixed` is the validated set-up, `moving`
    (the default, JAX-SPH's) the full-width lid."""
    require(lid_corners in LID_CORNERS, "lid_corners", f"{lid_corners!r} is not one of {list(LID_CORNERS)}")
    off = layers * dx
    lo, hi = np.array([off, off]), np.array([off + 1.0, off + 1.0])
    check_run_size(count(lo - off, hi + off, dx), dx, f"scene {name}")
    fluid = cartesian(lo, hi, dx)
    wall, normal = wall_layers(lo, hi, dx, layers)
    lid = wall[:, 1] > hi[1]
    if lid_corners == "fixed":
        x = wall[:, 0] - off
        lid &= ~((x < 0.0) | (x > 1.0))
    r = np.concatenate([fluid, wall])
    tag = np.concatenate([np.full(len(fluid), FLUID), np.where(lid, MOVING_WALL, WALL)]).astype(np.int32)
    u = np.zeros_like(r)
    u[len(fluid):][lid, 0] = lid_velocity
    nrm = np.concatenate([np.zeros_like(fluid), normal])
    side = 1.0 + 2 * off
    return Scene(name=name, dx=dx, domain=Domain(box=(side, side), periodic=(False, False)), material=material,
                 effects=effects, r=r, u=u, tag=tag, normal=nrm)


def setup(dx: float, re: float, method: str = "tvf", lid_velocity: float = 1.0, layers: int = 3):
    """The validated cavity at spacing dx and Reynolds number re: (scene with fixed lid corners, the
    method's numerics)."""
    require(method in METHODS, "method", f"{method!r} is not one of {list(METHODS)}")
    sc = scene(dx, material(re, lid_velocity), METHODS[method], layers=layers, lid_velocity=lid_velocity,
               lid_corners="fixed")
    return sc, numerics(method)


def offset(dx: float, layers: int = 3) -> float:
    """Shift between cavity coordinates (Ghia's [0, 1]^2) and scene coordinates."""
    return layers * dx
