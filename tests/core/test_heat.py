"""Thermal diffusion (Cleary 1998, `sph.heat`) and its wiring in the solver: effects.heat,
material.kappa / c_p, scene.T, T_fixed (Dirichlet), T_zones (inflow / outflow) and the thermal
time-step limit.

Analytical reference: in a periodic box T = T0 + A sin(k x) solves dT/dt = alpha lap T with
A(t) = A exp(-alpha k^2 t), alpha = kappa / (rho c_p). On a uniform lattice at rest the SPH operator
has this sine as an exact eigenmode; its eigenvalue approaches -alpha k^2 as O(dx^2) (quintic,
h = dx, measured: -1.12 % at dx = 0.05, -0.12 % at dx = 0.02; the solver's decay rate, with explicit
Euler's +dt alpha k^2 / 2, is -1.07 % and -0.10 %).
"""
import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import density, heat, walls
from sph.cases import channel
from sph.heat import TemperatureZone
from sph.rollout import scan_rollout
from sph.scene import Scene
from sph.state import FLUID
from sph_test_helpers import UNIT_SQUARE, jittered_lattice, lattice, per_particle, periodic_pairs

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

KAPPA, C_P = 7.313, 305.27          # the hot channel's fluid (JAX-SPH cases/ht.py)
MAT = sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0, kappa=KAPPA, c_p=C_P)
ALPHA = KAPPA / (MAT.rho_ref * C_P)
K = 2.0 * np.pi
T0, AMP = 1.0, 0.1
HEAT = sph.Effects(heat=True)


def _box_scene(r, T, u=None, T_fixed=None, zones=(), material=MAT, effects=HEAT, dx=0.05):
    r = np.asarray(r, float)
    return Scene(name="heat_box", dx=dx, domain=UNIT_SQUARE, material=material, effects=effects, r=r,
                 u=np.zeros_like(r) if u is None else np.asarray(u, float), tag=np.full(len(r), FLUID, np.int32),
                 T=np.asarray(T, float), T_fixed=T_fixed, T_zones=tuple(zones))


def _init(solver):
    """solver.init_fn() with the state built under jit (one compilation instead of seconds of
    op-by-op dispatch)."""
    r = jnp.asarray(solver.scene.r, solver.dtype)
    nbrs = solver.neighbors.allocate(r)
    return jax.jit(solver.state_at)(r, jnp.asarray(solver.scene.u, solver.dtype), nbrs), nbrs


def _rollout(solver, n_steps):
    state, nbrs = _init(solver)
    out, _, overflow = jax.jit(lambda s, nb: scan_rollout(solver.step_fn, s, nb, n_steps))(state, nbrs)
    assert not bool(overflow)
    return state, out


def _step(solver, state, nbrs, n=1):
    step = jax.jit(solver.step_fn)
    for k in range(1, n + 1):
        state, nbrs = step(state, nbrs, k)
    return state, nbrs


# -- operator vs. the analytical solution ------------------------------------------------------------
def test_operator_rate_of_a_sine_matches_alpha_k2():
    """dT/dt of the sine on a uniform lattice equals -alpha k^2 (T - T0) to O(dx^2): within 1.5 %
    at dx = 0.05 (the cell-list-independent brute-force pairs of the test helpers)."""
    dx = 0.05
    r = lattice(dx)
    kernel, pairs = periodic_pairs(r, dx)
    mass = jnp.full(len(r), MAT.rho_ref * dx**2)
    rho = per_particle(density.Summation(float(kernel.w(0.0))), pairs, mass=mass)
    T = jnp.asarray(T0 + AMP * np.sin(K * r[:, 0]))
    rate = np.asarray(per_particle(heat.Conduction(KAPPA, C_P), pairs, rho=rho, T=T, mass=mass).dTdt)
    exact = -ALPHA * K**2 * AMP * np.sin(K * r[:, 0])
    # the lattice sine is an eigenvector: the rate is a multiple of it at every particle
    ratio = np.sum(rate * exact) / np.sum(exact**2)
    np.testing.assert_allclose(rate, ratio * exact, rtol=0, atol=1e-9 * np.abs(exact).max())
    assert abs(ratio - 1.0) < 0.015, f"eigenvalue / (-alpha k^2) = {ratio:.5f}"
    assert ratio < 1.0  # the discrete Laplacian of a sine is weaker than the exact one


def test_sine_decays_as_exp_minus_alpha_k2_t():
    """Full solver (heat + momentum; particles free to move) on a uniform lattice at rest, dx = 0.05,
    to t = 0.5: the amplitude follows exp(-alpha k^2 t) within 1 % (measured 0.50 %), the fitted
    decay rate within 1.5 % (measured -1.07 %), and the particles do not move (every force cancels
    on the periodic uniform lattice)."""
    dx, t_end = 0.05, 0.5
    r = lattice(dx)
    solver = sph.build_solver(_box_scene(r, T0 + AMP * np.sin(K * r[:, 0]), dx=dx))
    n = solver.n_steps(t_end)
    state0, state = _rollout(solver, n)
    t = n * solver.dt

    def amplitude(s):
        return 2.0 * float(np.mean((np.asarray(s.T) - T0) * np.sin(K * np.asarray(s.r[:, 0]))))

    a0, a = amplitude(state0), amplitude(state)
    assert abs(a0 / AMP - 1.0) < 1e-12
    exact = np.exp(-ALPHA * K**2 * t)
    assert abs(a / AMP / exact - 1.0) < 0.01, f"A/A0 = {a / AMP:.6f}, exact {exact:.6f}"
    rate = -np.log(a / AMP) / t
    assert abs(rate / (ALPHA * K**2) - 1.0) < 0.015
    # at rest: no motion, and the mean temperature does not change
    assert float(jnp.max(jnp.abs(state.r - state0.r))) < 1e-12
    assert float(jnp.max(jnp.abs(state.u))) < 1e-10
    assert abs(float(jnp.mean(state.T)) - T0) < 1e-12


# -- conservation, Dirichlet particles, zones -------------------------------------------------------
def test_thermal_energy_is_conserved_in_a_periodic_box():
    """sum_i m_i c_p T_i is conserved to round-off in a periodic box without Dirichlet particles
    (the pair terms are antisymmetric), also with disordered, moving particles; the temperature
    field itself changes."""
    dx = 0.05
    r = jittered_lattice(dx, 0.2, seed=3)
    rng = np.random.default_rng(4)
    T = 1.0 + rng.uniform(0.0, 1.0, len(r))
    u = 0.5 * np.stack([-np.cos(K * r[:, 0]) * np.sin(K * r[:, 1]), np.sin(K * r[:, 0]) * np.cos(K * r[:, 1])], 1)
    solver = sph.build_solver(_box_scene(r, T, u=u, dx=dx))
    state0, state = _rollout(solver, 100)

    def energy(s):
        return float(jnp.sum(s.mass * MAT.c_p * s.T))

    assert float(jnp.max(jnp.abs(state.r - state0.r))) > 0.1 * dx        # particles moved
    assert float(jnp.max(jnp.abs(state.T - state0.T))) > 0.05            # heat was exchanged
    assert abs(energy(state) / energy(state0) - 1.0) < 1e-12
    assert float(jnp.min(state.T)) >= 1.0 and float(jnp.max(state.T)) <= 2.0  # maximum principle


def test_dirichlet_fluid_particle_keeps_its_temperature():
    """A fluid particle in scene.T_fixed keeps T while its neighbours heat up from it."""
    dx = 0.05
    r = lattice(dx)
    hot = int(np.argmin(np.linalg.norm(r - 0.5, axis=1)))
    T = np.ones(len(r))
    T[hot] = 2.0
    fixed = np.zeros(len(r), bool)
    fixed[hot] = True
    solver = sph.build_solver(_box_scene(r, T, T_fixed=fixed, dx=dx))
    state, nbrs = _step(solver, *_init(solver), n=20)
    T_end = np.asarray(state.T)
    assert T_end[hot] == 2.0
    near = np.linalg.norm(r - r[hot], axis=1) < 1.5 * dx
    near[hot] = False
    assert np.all(T_end[near] > 1.0 + 1e-3)


def _channel(effects=sph.Effects(walls="no_slip", heat=True, gravity=(2.3, 0.0)), **kw):
    return channel.scene(0.05, MAT, effects, **kw)


def test_dirichlet_walls_keep_their_temperature_and_free_walls_extrapolate():
    """Channel walls in T_fixed stay at T_ref / T_hot; walls outside T_fixed take the Shepard
    average of their fluid neighbours' temperature (Adami-style extrapolation, as JAX-SPH)."""
    sc = _channel()
    solver = sph.build_solver(sc, sph.Numerics(p_bg_factor=0.05))
    state, nbrs = _step(solver, *_init(solver), n=30)
    wall = sc.wall_mask
    np.testing.assert_array_equal(np.asarray(state.T)[wall], sc.T[wall])
    hot = channel.hot_wall_mask(sc.r, sc.dx)
    assert hot.sum() > 0 and np.all(sc.T[hot] == 1.23) and np.all(sc.T[wall & ~hot] == 1.0)
    assert float(jnp.max(state.T[sc.fluid_mask])) > 1.0 + 1e-3  # the fluid heats up

    # the same channel with free (non-Dirichlet) walls and a warm fluid layer: walls extrapolate
    T = np.where(sc.fluid_mask, 1.0 + sc.r[:, 1], 1.0)
    free = dataclasses.replace(sc, T=T, T_fixed=None, T_zones=())
    solver = sph.build_solver(free, sph.Numerics(p_bg_factor=0.05))
    state, nbrs = _init(solver)
    pairs = solver.pairs_fn(state.r, nbrs)
    fluid = jnp.asarray(free.fluid_mask, jnp.float64)
    expected = np.asarray(per_particle(lambda pp, i, j: walls.extrapolate(walls.fluid_weights(pp, j), j.T), pairs,
                                       fluid=fluid, T=jnp.asarray(T)))
    got = np.asarray(state.T)
    near = wall & np.asarray(jnp.sum(pairs.w * fluid[pairs.j], axis=1) > 0)
    np.testing.assert_allclose(got[near], expected[near], rtol=1e-10)
    assert np.all(got[near] > 1.0)  # not the initial wall value


def test_inflow_zone_sets_and_outflow_zone_freezes_the_temperature():
    """Fluid in an inflow zone takes the zone temperature after a step; fluid in an outflow zone
    (T = None) keeps its temperature although its neighbours differ; a Dirichlet particle inside
    the inflow zone keeps its own value."""
    dx = 0.05
    r = lattice(dx)
    rng = np.random.default_rng(0)
    T = 2.0 + rng.uniform(0.0, 1.0, len(r))
    inflow = TemperatureZone(axis=0, lo=0.0, hi=0.2, T=1.0)
    outflow = TemperatureZone(axis=0, lo=0.8, hi=1.0, T=None)
    fixed = np.zeros(len(r), bool)
    pinned = int(np.flatnonzero(r[:, 0] < 0.2)[0])
    fixed[pinned] = True
    solver = sph.build_solver(_box_scene(r, T, T_fixed=fixed, zones=(inflow, outflow), dx=dx))
    state, _ = _step(solver, *_init(solver), n=1)
    T1 = np.asarray(state.T)
    x = np.asarray(state.r[:, 0])
    in_zone = (x < 0.2) & ~fixed
    out_zone = x >= 0.8
    assert in_zone.sum() > 0 and out_zone.sum() > 0
    np.testing.assert_array_equal(T1[in_zone], 1.0)
    np.testing.assert_array_equal(T1[out_zone], T[out_zone])
    assert T1[pinned] == T[pinned]
    middle = ~(x < 0.2) & ~out_zone
    assert np.all(T1[middle] != T[middle])  # elsewhere diffusion acts


def test_channel_zones_follow_jax_sph():
    """The hot channel's zones: inflow x < 3 dx held at T_ref, outflow x >= 1 - 3 dx with dT/dt = 0."""
    sc = _channel()
    inflow, outflow = sc.T_zones
    assert (inflow.axis, inflow.hi, inflow.T) == (0, pytest.approx(0.15), 1.0)
    assert (outflow.axis, outflow.lo, outflow.T) == (0, pytest.approx(0.85), None)
    assert sc.domain.periodic == (True, False)
    assert np.all(sc.T_fixed == sc.wall_mask)


# -- time step ----------------------------------------------------------------------------------------
def test_dt_includes_the_thermal_limit_only_with_heat():
    dx = 0.05
    r = lattice(dx)
    hot_mat = dataclasses.replace(MAT, kappa=1.0, c_p=1.0)  # alpha = 1: the thermal limit binds
    on = sph.build_solver(_box_scene(r, np.ones(len(r)), material=hot_mat, dx=dx))
    h, cfl = dx, on.numerics.cfl
    assert on.dt_limits["thermal"] == pytest.approx(cfl * h**2 / 1.0, rel=1e-12)
    assert on.dt_limits["thermal"] < on.dt_limits["convective"]
    assert on.dt == pytest.approx(on.dt_limits["thermal"], rel=1e-12)
    assert on.dt == min(v for k, v in on.dt_limits.items() if k != "dt")

    weak = sph.build_solver(_box_scene(r, np.ones(len(r)), dx=dx))  # alpha = 0.024: does not bind
    assert weak.dt_limits["thermal"] == pytest.approx(cfl * h**2 / ALPHA, rel=1e-12)
    assert weak.dt == pytest.approx(weak.dt_limits["convective"], rel=1e-12)

    off_scene = Scene(name="cold", dx=dx, domain=UNIT_SQUARE, material=hot_mat, effects=sph.Effects(), r=r,
                      u=np.zeros_like(r), tag=np.full(len(r), FLUID, np.int32))
    off = sph.build_solver(off_scene)
    assert "thermal" not in off.dt_limits
    assert off.dt == pytest.approx(off.dt_limits["convective"], rel=1e-12)
    state, _ = _init(off)
    assert state.T is None


# -- trajectories ---------------------------------------------------------------------------------
def test_temperature_frames_are_stored_and_a_run_resumes_from_them(tmp_path):
    """`keep=("temperature",)` stores T per frame (LagrangeBench layout) and in the checkpoint, so a
    heat run that stops half-way resumes to the same final temperature as an uninterrupted run
    (same steps, same arithmetic: equal to round-off), whose amplitude follows exp(-alpha k^2 t)
    within 1 % (the operator's error at dx = 0.05 is 1.07 %, see the module doc; t is short)."""
    from sph import simulate
    from lab import io

    dx, t_end, every = 0.05, 0.1, 10
    r = lattice(dx)
    solver = sph.build_solver(_box_scene(r, T0 + AMP * np.sin(K * r[:, 0]), dx=dx))
    n = solver.n_steps(t_end)
    state0, nbrs0 = _init(solver)

    def writer(path):
        return io.TrajectoryWriter.create(path, solver.scene.tag, 2, keep=("temperature",))

    with writer(tmp_path / "full.h5") as w:
        full = simulate.run(solver, state0, nbrs0, t_end, every, w, progress=False)
    with writer(tmp_path / "part.h5") as w:
        simulate.run(solver, state0, nbrs0, t_end, every, w, progress=False, n_steps=(n // every // 2) * every)
    with io.TrajectoryWriter.open(tmp_path / "part.h5") as w:
        state, nbrs, step = simulate.resume(solver, w)
        assert state.T is not None and 0 < step < n
        simulate.run(solver, state, nbrs, t_end, every, w, progress=False, step0=step)
    a, b = io.read_trajectory(tmp_path / "full.h5"), io.read_trajectory(tmp_path / "part.h5")
    assert a["temperature"].shape == (len(a["time"]), len(r))
    np.testing.assert_allclose(a["temperature"][0], solver.scene.T, rtol=0, atol=1e-15)
    np.testing.assert_allclose(b["temperature"], a["temperature"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(a["temperature"][-1], np.asarray(full.state.T), rtol=0, atol=1e-15)
    amp = 2.0 * np.mean((a["temperature"][-1] - T0) * np.sin(K * a["position"][-1][:, 0]))
    assert abs(amp / AMP / np.exp(-ALPHA * K**2 * a["time"][-1]) - 1.0) < 0.01


def test_keeping_temperature_without_heat_names_the_field(tmp_path):
    from lab import io

    r = lattice(0.1)
    solver = sph.build_solver(Scene(name="no_heat", dx=0.1, domain=UNIT_SQUARE, material=sph.Material(),
                                    effects=sph.Effects(), r=r, u=np.zeros_like(r),
                                    tag=np.full(len(r), FLUID, np.int32)))
    state, _ = _init(solver)
    with io.TrajectoryWriter.create(tmp_path / "t.h5", solver.scene.tag, 2, keep=("temperature",)) as w:
        with pytest.raises(ValueError, match="keeps 'temperature', but the state has no T"):
            w.append(state, 0, 0.0)
