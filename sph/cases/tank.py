"""Water in a closed rectangular tank under gravity: the dam break (Colagrossi & Landrini 2003;
Martin & Moyce 1952) and the hydrostatic tank at rest.

Tank interior [0, L_tank] x [0, H_tank] (shifted by `layers * dx` into the scene box), water column
[0, width] x [0, height] against the left wall, gravity g in -y. u_ref = sqrt(2 g height), the
largest free-fall speed of the column.
"""
import jax.numpy as jnp
import numpy as np

from ..config import Effects, Material
from ..domain import Domain
from ..lattice import cartesian, check_run_size, count, wall_layers
from ..scene import Scene
from ..state import FLUID, WALL, ParticleState


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
