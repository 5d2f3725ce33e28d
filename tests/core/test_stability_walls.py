"""Wall impact: fluid thrown at the bottom wall of a small closed tank at several times u_ref must not
penetrate it (no fluid particle beyond the wall face by more than dx/2, at any step), for standard
SPH with no-slip walls (Adami 2012) and for Riemann SPH with its one-sided wall Riemann problem.

The tank is 1 x 1 with 3 wall layers, dx = 0.05, u_ref = 1 (c_ref = 10), no gravity, eta = 0.01. A
single particle or a 4 x 4 block starts at rest-frame height 0.3 (block centre) moving straight down
at U, and runs for three times its free-flight time to the wall. "Standard SPH" is the dam-break
configuration (continuity density, optionally Monaghan artificial viscosity); two known limitations
are recorded as strict xfails:

- standard SPH with summation density: an isolated particle (and the edge of a block) has
  rho = sum m W < rho_ref, so a negative pressure, which the Adami wall copies: the wall attracts
  the particle, which is sucked several dx into it;
- standard SPH (continuity) with a block at 5 u_ref (Ma 0.5, far outside weak compressibility): the
  block's front row is pushed ~0.8 dx beyond the face before the wall pressure stops it. Riemann
  walls hold at the same speed.
"""
import jax
import numpy as np
import pytest

import sph
from sph.domain import Domain
from sph.lattice import cartesian, wall_layers
from sph.scene import Scene
from sph.state import FLUID, WALL

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

DX = 0.05
LAYERS = 3
OFF = LAYERS * DX
HEIGHT = 0.3  # centre of the fluid above the bottom wall face

STANDARD = sph.Effects(walls="no_slip", density_evolution=True)
STANDARD_AV = sph.Effects(walls="no_slip", density_evolution=True, artificial_viscosity=0.1)
SUMMATION = sph.Effects(walls="no_slip")
RIEMANN = sph.Effects(walls="no_slip", riemann=True, density_evolution=True)


def _scene(effects, speed, block):
    """A `block` x `block` lattice of fluid at height HEIGHT moving down at `speed`, in a 1 x 1 tank."""
    lo, hi = np.array([OFF, OFF]), np.array([OFF + 1.0, OFF + 1.0])
    centre = np.array([OFF + 0.5, OFF + HEIGHT])
    fluid = cartesian(centre - block * DX / 2, centre + block * DX / 2, DX)
    wall, normal = wall_layers(lo, hi, DX, LAYERS)
    r = np.concatenate([fluid, wall])
    tag = np.concatenate([np.full(len(fluid), FLUID), np.full(len(wall), WALL)]).astype(np.int32)
    u = np.zeros_like(r)
    u[: len(fluid), 1] = -speed
    return Scene(name="throw", dx=DX, domain=Domain(box=(1.0 + 2 * OFF, 1.0 + 2 * OFF), periodic=(False, False)),
                 material=sph.Material(eta=0.01, u_ref=1.0), effects=effects, r=r, u=u, tag=tag,
                 normal=np.concatenate([np.zeros_like(fluid), normal]))


def _throw(effects, speed, block):
    """Step by step: the deepest excursion of any fluid particle beyond any wall face (in dx, > 0 is
    inside the wall), the smallest gap to the bottom face (dx), the largest upward speed after the
    closest approach, and whether everything stayed finite."""
    scene = _scene(effects, speed, block)
    solver = sph.build_solver(scene)
    state, nbrs = solver.init_fn()
    step = jax.jit(solver.step_fn)
    fluid = scene.fluid_mask
    free_flight = (HEIGHT - block * DX / 2) / speed
    depth, gap, t_gap, rebound, finite = -np.inf, np.inf, 0.0, -np.inf, True
    for k in range(1, solver.n_steps(3.0 * free_flight) + 1):
        new_state, new_nbrs = step(state, nbrs, k)
        if bool(new_nbrs.did_buffer_overflow):  # redo the step with a re-allocated list
            new_state, new_nbrs = step(state, solver.neighbors.allocate(state.r), k)
            assert not bool(new_nbrs.did_buffer_overflow)
        state, nbrs = new_state, new_nbrs
        r = np.asarray(state.r)[fluid] - OFF
        u = np.asarray(state.u)[fluid]
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(u))):
            finite = False
            break
        depth = max(depth, float(np.max(np.maximum(-r, r - 1.0))) / DX)
        if r[:, 1].min() / DX < gap:
            gap, t_gap = r[:, 1].min() / DX, k * solver.dt
        if k * solver.dt > t_gap:
            rebound = max(rebound, float(u[:, 1].mean()))
    return {"depth": depth, "gap": gap, "rebound": rebound, "finite": finite}


def _assert_held(res):
    assert res["finite"]
    assert res["gap"] < 1.0, f"the fluid never reached the wall (closest gap {res['gap']:.2f} dx)"
    assert res["depth"] <= 0.5, f"a fluid particle went {res['depth']:.2f} dx beyond a wall face"


@pytest.mark.parametrize("effects, speed, block", [
    pytest.param(STANDARD, 5.0, 1, id="standard-particle-5u_ref"),
    pytest.param(STANDARD, 3.0, 4, id="standard-block-3u_ref"),
    pytest.param(STANDARD_AV, 3.0, 4, id="standard_av-block-3u_ref"),
    pytest.param(RIEMANN, 5.0, 1, id="riemann-particle-5u_ref"),
    pytest.param(RIEMANN, 5.0, 4, id="riemann-block-5u_ref"),
])
def test_fluid_thrown_at_wall_does_not_penetrate(effects, speed, block):
    res = _throw(effects, speed, block)
    _assert_held(res)
    assert res["rebound"] > -0.1 * speed, "the fluid did not stop at the wall"


@pytest.mark.parametrize("effects, speed, block", [
    pytest.param(SUMMATION, 3.0, 1, id="summation-particle-3u_ref"),
    pytest.param(STANDARD, 5.0, 4, id="standard-block-5u_ref"),
])
@pytest.mark.xfail(strict=True, raises=AssertionError, reason="known limitation, see the module docstring")
def test_known_wall_penetration(effects, speed, block):
    _assert_held(_throw(effects, speed, block))


@pytest.mark.parametrize("effects, speed, block, measured", [
    pytest.param(SUMMATION, 3.0, 1, 3.91, id="summation-particle-3u_ref"),
    pytest.param(STANDARD, 5.0, 4, 0.82, id="standard-block-5u_ref"),
])
def test_known_wall_penetration_does_not_get_worse(effects, speed, block, measured):
    """The size of each known penetration, pinned (measured 2026-12-06: 3.91 dx and 0.82 dx): it may
    shrink (the xfail above then turns into a pass and fails as strict), not grow by more than 10 %."""
    res = _throw(effects, speed, block)
    assert res["finite"]
    assert 0.5 < res["depth"] <= 1.1 * measured, f"penetration {res['depth']:.2f} dx, pinned at {measured} dx"
