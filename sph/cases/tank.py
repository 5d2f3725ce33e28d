"""Water in a closed rectangular tank under gravity: the dam break (Colagrossi & Landrini 2003;
Martin & Moyce 1952) and the hydrostatic tank at rest.

Tank interior [0, L_tank] x [0, H_tank] (shifted by `layers * dx` into the scene box), water column
[0, width] x [0, height] against the left wall, gravity g in -y. u_ref = sqrt(2 g height), the
largest free-fall speed of the column.

The validated dam break (experiments/dambreak2d, JAX-SPH Fig. 8; units rho_ref = g = H = 1): the tank
DAM_BREAK_TANK, Riemann SPH with DAM_BREAK_EFFECTS and DAM_BREAK_NUMERICS, viscosity DAM_BREAK_ETA,
a hydrostatic start (`hydrostatic`); its comparisons with Buchner (2002) and Martin & Moyce (1952)
are experiments/dambreak2d/analysis.py's.
"""
import dataclasses
import math

import jax.numpy as jnp
import numpy as np

from ..config import Effects, Material, Numerics
from ..domain import Domain
from ..errors import require
from ..lattice import cartesian, check_run_size, count, wall_layers
from ..scene import Scene
from ..state import FLUID, WALL, ParticleState

DAM_BREAK_TANK = {"tank_length": 5.366, "tank_height": 2.0, "layers": 3}
"""The closed tank of the dam break (interior 5.366 H x 2 H, 3 wall layers); the column is 2 x 1 (Fig. 8)
or 1 x 1 (the surge front of Martin & Moyce)."""

DAM_BREAK_EFFECTS = Effects(riemann=True, density_evolution=True, density_reinit_every=20, gravity=(0.0, -1.0),
                            walls="free_slip")
"""Riemann SPH with Shepard re-initialization every 20 steps (Zhang 2017) and free-slip walls (no boundary
layer is resolvable at dx = 0.02)."""

DAM_BREAK_NUMERICS = Numerics(kernel="quintic", h_factor=1.0, cfl=0.25, c_ref_factor=10.0 * math.sqrt(2.0),
                              eta_limiter=3.0, dtype="float64")
"""c_ref = 10 sqrt(2) u_ref = 20 sqrt(g H) as JAX-SPH's validation/db2d.sh (with 10 u_ref the first impact
compresses particles in the far corner by 3.4 %)."""

DAM_BREAK_ETA = 5.0e-5
"""JAX-SPH's viscosity of the dam break (rho_ref = 1)."""


def scene(dx: float, material: Material, effects: Effects, width: float, height: float, tank_length: float,
          tank_height: float, layers: int = 3, name: str = "tank") -> Scene:
    off = layers * dx
    lo, hi = np.array([off, off]), np.array([off + tank_length, off + tank_height])
    check_run_size(count([off, off], [off + width, off + height], dx) + count(lo - off, hi + off, dx)
                   - count(lo, hi, dx), dx, f"scene {name}")
    fluid = cartesian([off, off], [off + width, off + height], dx)
    wall, normal = wall_layers(lo, hi, dx, layers)
    r = np.concatenate([fluid, wall])
    tag = np.concatenate([np.full(len(fluid), FLUID), np.full(len(wall), WALL)]).astype(np.int32)
    nrm = np.concatenate([np.zeros_like(fluid), normal])
    box = (tank_length + 2 * off, tank_height + 2 * off)
    return Scene(name=name, dx=dx, domain=Domain(box=box, periodic=(False, False)), material=material,
                 effects=effects, r=r, u=np.zeros_like(r), tag=tag, normal=nrm)


def u_ref(g: float, height: float) -> float:
    """Reference speed sqrt(2 g H) of a column of height H."""
    return float(np.sqrt(2.0 * g * height))


def hydrostatic(state: ParticleState, eos, rho_ref: float, g: float, surface: float) -> ParticleState:
    """The fluid at rest in hydrostatic balance: p = rho_ref g (surface - y) and rho = EoS^-1(p) on the
    fluid particles (walls keep theirs; the wall pass extrapolates them, Adami 2012 eq. 27). Starting a
    column from uniform density instead lets it settle under gravity first, ringing with a compression
    wave of amplitude ~ rho_ref g H / c_ref^2 that adds to later impact peaks. `surface` is the free
    surface height in scene coordinates (tank offset + column height)."""
    fluid = state.tag == FLUID
    p = rho_ref * g * (surface - state.r[:, 1])
    return state.replace(p=jnp.where(fluid, p, state.p), rho=jnp.where(fluid, eos.rho(p), state.rho))


def offset(dx: float, layers: int = 3) -> float:
    """Shift between tank coordinates (the interior from 0) and scene coordinates: the wall layers."""
    return layers * dx


def surface(dx: float, height: float, layers: int = 3) -> float:
    """The free surface of a column of `height`, in scene coordinates (for `hydrostatic`)."""
    return offset(dx, layers) + height


AT_REST_EFFECTS = {
    "sph": Effects(density_evolution=True, gravity=(0.0, -1.0), walls="no_slip"),
    "riemann": DAM_BREAK_EFFECTS,
}
"""A tank at rest: standard SPH with continuity density and no-slip walls (the recommended method:
it settles to |u| ~ 6e-5 sqrt(gH) by t = 10 sqrt(H/g), dx = H / 10), or the dam break's Riemann SPH
with free-slip walls, which does not settle: spurious speeds grow to ~1.3 % of sqrt(gH) by
t = 10 sqrt(H/g) and the free surface rises ~0.7 dx. Measured (tests/core/test_tank_at_rest.py): on
the hydrostatic start the Riemann continuity equation gives drho/dt ~ +1.5e-2 sqrt(g/H) rho_ref on
the particles within a support of the free surface, ~140x standard SPH's: the pressure-jump term of
the Riemann velocity U* (Zhang 2017b eq. 7) acts as a density diffusion on the hydrostatic pressure
gradient, which a truncated kernel at the free surface does not balance (the known lack of a
hydrostatic correction of density-diffusion terms, cf. Antuono et al. 2012 for delta-SPH). Switching
the limiter off (beta = c) halves the growth (0.5 %, no longer growing); neither no-slip walls nor
dropping the re-initialization removes it. So: Riemann SPH's behaviour at a hydrostatic free
surface, not a defect of the walls; use standard SPH for a tank at rest."""


def at_rest(dx: float, width: float = 1.0, height: float = 0.5, method: str = "sph", g: float = 1.0,
            eta: float = 0.01, layers: int = 3):
    """Water of `height` filling a tank of `width` at rest under gravity g (units rho_ref = 1): (scene,
    numerics, start) with start(solver) -> (state, nbrs) the hydrostatic state (`hydrostatic`), the
    tank twice as tall as the water. u_ref = sqrt(2 g height) sets c_ref = 10 u_ref."""
    require(method in AT_REST_EFFECTS, "method", f"{method!r} is not one of {list(AT_REST_EFFECTS)}")
    fx = dataclasses.replace(AT_REST_EFFECTS[method], gravity=(0.0, -float(g)))
    mat = Material(rho_ref=1.0, eta=eta, u_ref=u_ref(g, height))
    sc = scene(dx, mat, fx, width=width, height=height, tank_length=width, tank_height=2.0 * height,
               layers=layers, name="tank_at_rest")
    numerics = DAM_BREAK_NUMERICS if method == "riemann" else Numerics()

    def start(solver):
        state, nbrs = solver.init_fn()
        return hydrostatic(state, solver.eos, 1.0, g, surface(dx, height, layers)), nbrs

    return sc, numerics, start
