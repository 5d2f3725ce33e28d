"""Generalized wall boundary condition (sph.walls, Adami, Hu & Adams 2012) and its use in the step.

Operator checks with exact answers: the wall-pressure extrapolation (eq. 27) reproduces a
hydrostatic field exactly (a linear field plus the gravity term), the no-slip velocity inverts a
uniform fluid velocity, free slip mirrors only its normal part. Then a tank at rest: the
time-averaged pressure matches rho g (surface - y) for standard SPH and Riemann SPH.
"""
import jax
import numpy as np
import pytest

import sph
from sph import walls
from sph.cases import tank
from sph_test_helpers import per_particle

DX = 0.05
G = 1.0


def _tank(effects, eta=0.01, height=1.0):
    mat = sph.Material(eta=eta, u_ref=tank.u_ref(G, height))
    return tank.scene(DX, mat, effects, width=1.0, height=height, tank_length=1.0, tank_height=height + 0.2)


@pytest.fixture(scope="module")
def at_rest():
    """Solver, initial state and pairs of a 1 x 1 water block in a closed tank (no dynamics)."""
    solver = sph.build_solver(_tank(sph.Effects(gravity=(0.0, -G), walls="no_slip", density_evolution=True)))
    state, nbrs = solver.init_fn()
    return solver, state, solver.pairs_fn(state.r, nbrs)


def _extrapolated(pairs, fluid, **fields):
    """The wall pass's Shepard extrapolations (`walls.WallExtrapolation`) for every particle."""
    return per_particle(walls.WallExtrapolation(), pairs, fluid=jax.numpy.asarray(fluid, float), **fields)


def _has_fluid_neighbours(pairs, fluid):
    return np.asarray(jax.numpy.sum(pairs.w * jax.numpy.asarray(fluid, float)[pairs.j], axis=1) > 0)


def test_wall_pressure_extrapolates_hydrostatics_exactly(at_rest):
    """p_f = rho g (H - y_f) on the fluid gives p_w = rho g (H - y_w) on every wall particle that has
    fluid neighbours, including those below and beside the column (eq. 27 is exact for it)."""
    solver, state, pairs = at_rest
    fluid = np.asarray(state.tag) == sph.FLUID
    y = np.asarray(state.r)[:, 1]
    surface = 1.0 + 3 * DX
    p = np.where(fluid, G * (surface - y), 0.0)
    g = np.broadcast_to(np.array([0.0, -G]), state.r.shape)
    got = _extrapolated(pairs, fluid, p=p, rho=state.rho * 0 + 1.0, g=g, u=np.zeros_like(g))
    p_w = np.asarray(got.p)
    near = (~fluid) & _has_fluid_neighbours(pairs, fluid)
    assert near.sum() > 100
    np.testing.assert_allclose(p_w[near], G * (surface - y[near]), atol=1e-12)


def test_no_slip_and_free_slip_wall_velocity(at_rest):
    """Uniform fluid velocity U: u^_w = U, so no slip gives 2 u_w - U and free slip keeps the
    tangential part of U and mirrors the normal part about u_w (walls at rest: -U_n)."""
    solver, state, pairs = at_rest
    fluid = np.asarray(state.tag) == sph.FLUID
    U = np.array([0.7, -0.4])
    u = np.where(fluid[:, None], U, 0.0)
    zero = np.zeros(len(fluid))
    u_hat = np.asarray(_extrapolated(pairs, fluid, p=zero, rho=zero + 1.0, g=np.zeros_like(u), u=u).u_hat)
    near = (~fluid) & _has_fluid_neighbours(pairs, fluid)
    np.testing.assert_allclose(u_hat[near], np.broadcast_to(U, u_hat[near].shape), atol=1e-12)
    np.testing.assert_allclose(np.asarray(walls.velocity(u_hat, np.zeros_like(u)))[near], -U[None].repeat(near.sum(), 0))
    n = solver.scene.normal
    slip = np.asarray(walls.velocity(u_hat, np.zeros_like(u), n))[near]
    n_near = n[near]
    u_n = np.sum(slip * n_near, axis=1)
    np.testing.assert_allclose(u_n, -(n_near @ U), atol=1e-12)                   # normal part mirrored
    np.testing.assert_allclose(slip - u_n[:, None] * n_near,
                               U - (n_near @ U)[:, None] * n_near, atol=1e-12)  # tangential part kept


def test_walls_do_not_move_and_get_no_acceleration(at_rest):
    solver, state, _ = at_rest
    wall = np.asarray(state.tag) != sph.FLUID
    step = jax.jit(solver.step_fn)
    s, nbrs = state, solver.neighbors.allocate(state.r)
    for k in range(1, 20):
        s, nbrs = step(s, nbrs, k)
    np.testing.assert_array_equal(np.asarray(s.r)[wall], np.asarray(state.r)[wall])
    assert np.all(np.asarray(s.dudt)[wall] == 0) and np.all(np.asarray(s.v)[wall] == 0)
    assert np.abs(np.asarray(s.dudt)[~wall]).max() > 0


@pytest.mark.parametrize("riemann", [False, True], ids=["standard", "riemann"])
def test_tank_at_rest_is_hydrostatic(riemann):
    """Water at rest under gravity: the pressure, averaged over t in [2, 4] (the initial acoustic
    transient is damped by viscosity), matches rho g (surface - y) within 3 % of rho g H at every
    depth. The surface is the mean top particle row + dx/2. No fluid particle enters a wall."""
    fx = sph.Effects(gravity=(0.0, -G), walls="no_slip", riemann=riemann, density_evolution=True)
    solver = sph.build_solver(_tank(fx))
    state, nbrs = solver.init_fn()
    fluid = np.asarray(state.tag) == sph.FLUID
    step = jax.jit(solver.step_fn)
    n = solver.n_steps(4.0)
    ys, ps, tops = [], [], []
    for k in range(1, n + 1):
        state, nbrs = step(state, nbrs, k)
        if k > n // 2 and k % 25 == 0:
            y = np.asarray(state.r)[fluid, 1] - 3 * DX
            ys.append(y)
            ps.append(np.asarray(state.p)[fluid])
            tops.append(y.max() + DX / 2)
    assert not bool(nbrs.did_buffer_overflow)
    y, p, surface = np.concatenate(ys), np.concatenate(ps), np.mean(tops)
    assert abs(surface - 1.0) < 0.02
    for lo in np.arange(0.0, 0.9, 0.1):
        band = (y >= lo) & (y < lo + 0.1)
        assert abs(p[band].mean() - G * np.mean(surface - y[band])) < 0.03, f"depth band y in [{lo:.1f}, {lo + 0.1:.1f})"
    r = np.asarray(state.r)[fluid] - 3 * DX
    assert r.min() > -DX / 2 and r[:, 0].max() < 1.0 + DX / 2


@pytest.mark.parametrize("riemann", [False, True], ids=["standard", "riemann"])
def test_hydrostatic_start_stays_at_rest(riemann):
    """`tank.hydrostatic` balances gravity by the pressure gradient, so the column stays at rest: its
    fastest particle over t <= 0.5 moves below 0.1 g H / c_ref. Started at uniform density instead,
    the column settles with an acoustic compression wave whose velocity amplitude is
    dp / (rho c) = g H / c_ref (linear acoustics): the measured maximum lies within 25 % of it."""
    fx = sph.Effects(gravity=(0.0, -G), walls="no_slip", riemann=riemann, density_evolution=True)
    solver = sph.build_solver(_tank(fx))
    c_ref = float(solver.eos.c_ref)
    step = jax.jit(solver.step_fn)
    v_max = {}
    for start in ("uniform", "hydrostatic"):
        state, nbrs = solver.init_fn()
        if start == "hydrostatic":
            state = tank.hydrostatic(state, solver.eos, 1.0, G, surface=3 * DX + 1.0)
        fluid = np.asarray(state.tag) == sph.FLUID
        v_max[start] = 0.0
        for k in range(1, solver.n_steps(0.5) + 1):
            state, nbrs = step(state, nbrs, k)
            v_max[start] = max(v_max[start], float(np.abs(np.asarray(state.v)[fluid]).max()))
        assert np.all(np.isfinite(np.asarray(state.rho)))
    scale = G * 1.0 / c_ref
    assert abs(v_max["uniform"] / scale - 1) < 0.25, v_max
    assert v_max["hydrostatic"] < 0.1 * scale, v_max
