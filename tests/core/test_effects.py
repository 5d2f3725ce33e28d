"""The step is assembled from exactly the declared effects (solver.py's contract).

Checked robustly, without relying on numbers: the physics functions the step calls while it is
traced are recorded (their modules are patched with recording wrappers), the size of the step's
jaxpr grows when an effect is added, and a scene without TVF keeps v = u and dv/dt = 0 exactly.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import density, heat, momentum, riemann, walls
from sph.cases import tank, tgv

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

DX = 0.05
MAT = sph.Material(eta=0.01)
PHYSICS = {
    "density.summation": (density, "summation"),
    "density.continuity": (density, "continuity"),
    "density.reinitialize": (density, "reinitialize"),
    "momentum.acceleration": (momentum, "acceleration"),
    "momentum.background_acceleration": (momentum, "background_acceleration"),
    "riemann.continuity": (riemann, "continuity"),
    "riemann.acceleration": (riemann, "acceleration"),
    "momentum.artificial_viscosity": (momentum, "artificial_viscosity"),
    "walls.pressure": (walls, "pressure"),
    "walls.extrapolate": (walls, "extrapolate"),
    "heat.temperature_rate": (heat, "temperature_rate"),
}
WALL_PASS = {"walls.pressure", "walls.extrapolate"}
HOT = sph.Material(eta=0.01, kappa=0.1, c_p=1.0)
SCENES = {  # name -> (scene factory, physics the step must call, has temperature)
    "tank": (lambda: tank.scene(0.1, MAT, sph.Effects(walls="no_slip", gravity=(0.0, -1.0), density_evolution=True),
                                width=0.5, height=0.5, tank_length=1.0, tank_height=1.0),
             {"density.continuity", "momentum.acceleration"} | WALL_PASS, False),
    "tank_riemann": (lambda: tank.scene(0.1, MAT, sph.Effects(walls="no_slip", gravity=(0.0, -1.0), riemann=True,
                                                              density_evolution=True),
                                        width=0.5, height=0.5, tank_length=1.0, tank_height=1.0),
                     {"riemann.continuity", "riemann.acceleration"} | WALL_PASS, False),
    "tank_artificial_viscosity": (
        lambda: tank.scene(0.1, MAT, sph.Effects(walls="no_slip", density_evolution=True, artificial_viscosity=0.1),
                           width=0.5, height=0.5, tank_length=1.0, tank_height=1.0),
        {"density.continuity", "momentum.acceleration", "momentum.artificial_viscosity"} | WALL_PASS, False),
    "tank_heat": (lambda: _with_temperature(tank.scene(0.1, MAT, sph.Effects(walls="no_slip"), width=0.5, height=0.5,
                                                       tank_length=1.0, tank_height=1.0)),
                  {"density.summation", "momentum.acceleration", "walls.extrapolate", "heat.temperature_rate"}
                  | WALL_PASS, True),
    "tgv_heat": (lambda: _with_temperature(tgv.scene(DX, MAT, sph.Effects())),
                 {"density.summation", "momentum.acceleration", "heat.temperature_rate"}, True),
}


def _with_temperature(scene):
    """The same scene with heat declared: conductivity, a temperature field, Dirichlet walls."""
    import dataclasses
    return dataclasses.replace(scene, material=HOT, effects=dataclasses.replace(scene.effects, heat=True),
                               T=1.0 + scene.r[:, 0], T_fixed=scene.wall_mask)
CASES = {
    "none": (sph.Effects(), {"density.summation", "momentum.acceleration"}),
    "tvf": (sph.Effects(tvf=True),
            {"density.summation", "momentum.acceleration", "momentum.background_acceleration"}),
    "gravity": (sph.Effects(gravity=(0.0, -1.0)), {"density.summation", "momentum.acceleration"}),
    "density_evolution": (sph.Effects(density_evolution=True), {"density.continuity", "momentum.acceleration"}),
    "reinit": (sph.Effects(density_evolution=True, density_reinit_every=5),
               {"density.continuity", "density.reinitialize", "momentum.acceleration"}),
    "riemann": (sph.Effects(riemann=True, density_evolution=True), {"riemann.continuity", "riemann.acceleration"}),
}


@pytest.fixture
def recorder(monkeypatch):
    """Replace the physics functions by wrappers that log (name, args) and call the original."""
    calls = []
    for name, (module, attr) in PHYSICS.items():
        original = getattr(module, attr)

        def wrapper(*args, _name=name, _original=original, **kwargs):
            calls.append((_name, args, kwargs))
            return _original(*args, **kwargs)

        monkeypatch.setattr(module, attr, wrapper)
    return calls


@pytest.fixture(scope="module")
def state_and_list():
    """A state and neighbour list of the TGV lattice, reused to trace every solver's step (same
    particles, domain and cutoff, so the list is valid for each of them)."""
    solver = sph.build_solver(tgv.scene(DX, MAT, sph.Effects()))
    return solver.init_fn()


def _solver(effects):
    return sph.build_solver(tgv.scene(DX, MAT, effects))


def _count_eqns(jaxpr):
    """Number of equations in a jaxpr, including those of nested jaxprs (jit, cond, scan, ...)."""
    jaxpr = getattr(jaxpr, "jaxpr", jaxpr)
    total = 0
    for eqn in jaxpr.eqns:
        total += 1
        for value in eqn.params.values():
            for sub in value if isinstance(value, (tuple, list)) else (value,):
                if hasattr(sub, "eqns") or hasattr(getattr(sub, "jaxpr", None), "eqns"):
                    total += _count_eqns(sub)
    return total


def _step_jaxpr(effects, state_and_list):
    state, nbrs = state_and_list
    return jax.make_jaxpr(_solver(effects).step_fn)(state, nbrs, 1)


@pytest.mark.parametrize("case", list(CASES))
def test_step_calls_only_declared_physics(case, recorder, state_and_list):
    effects, expected = CASES[case]
    _step_jaxpr(effects, state_and_list)
    called = {name for name, _, _ in recorder}
    assert called == expected, f"{case}: step called {sorted(called)}, expected {sorted(expected)}"
    for name, args, kwargs in recorder:
        if name == "momentum.acceleration":  # the TVF stress terms are traced only with TVF
            tvf = kwargs["tvf"] if "tvf" in kwargs else args[4]
            assert tvf is effects.tvf


def test_riemann_init_does_not_evaluate_summation(recorder):
    state, _ = _solver(CASES["riemann"][0]).init_fn()
    assert not any(name == "density.summation" for name, _, _ in recorder)
    np.testing.assert_array_equal(np.asarray(state.rho), MAT.rho_ref)  # evolved density starts at rho_ref


@pytest.mark.parametrize("base,extended", [("none", "tvf"), ("none", "gravity"), ("density_evolution", "reinit")])
def test_adding_an_effect_grows_the_step(base, extended, state_and_list):
    n_base = _count_eqns(_step_jaxpr(CASES[base][0], state_and_list))
    n_ext = _count_eqns(_step_jaxpr(CASES[extended][0], state_and_list))
    assert n_ext > n_base, f"{extended}: {n_ext} equations, {base}: {n_base}"


def test_step_without_tvf_keeps_transport_velocity_equal_to_velocity(state_and_list):
    solver = _solver(sph.Effects())
    state, nbrs = state_and_list
    step = jax.jit(solver.step_fn)
    for k in range(1, 4):
        state, nbrs = step(state, nbrs, k)
    assert state.T is None
    assert bool(jnp.all(state.dvdt == 0.0))
    assert bool(jnp.all(state.v == state.u))
    assert float(jnp.max(jnp.abs(state.dudt))) > 0.0


def test_gravity_is_added_to_the_acceleration(state_and_list):
    """With gravity g, du/dt differs from the gravity-free step by exactly g for every particle."""
    state, nbrs = state_and_list
    g = (0.3, -2.0)
    # a common fixed time step, so positions and densities agree and only the body force differs
    num = sph.Numerics(dt=1e-3)
    s_0, _ = jax.jit(sph.build_solver(tgv.scene(DX, MAT, sph.Effects()), num).step_fn)(state, nbrs, 1)
    s_g, _ = jax.jit(sph.build_solver(tgv.scene(DX, MAT, sph.Effects(gravity=g)), num).step_fn)(state, nbrs, 1)
    np.testing.assert_array_equal(np.asarray(s_g.r), np.asarray(s_0.r))
    np.testing.assert_allclose(np.asarray(s_g.dudt - s_0.dudt), np.broadcast_to(np.array(g), s_0.dudt.shape),
                               rtol=0, atol=1e-12 * float(jnp.max(jnp.abs(s_0.dudt))))


@pytest.mark.parametrize("name", list(SCENES))
def test_wall_and_heat_passes_only_when_declared(name, recorder):
    """Walls, heat and artificial viscosity are traced into the step exactly when declared; the
    temperature field exists exactly when heat is declared (no field, no heat work otherwise)."""
    make, expected, has_T = SCENES[name]
    solver = sph.build_solver(make())
    state, nbrs = solver.init_fn()
    recorder.clear()
    jax.make_jaxpr(solver.step_fn)(state, nbrs, 1)
    called = {n for n, _, _ in recorder}
    assert called == expected, f"{name}: step called {sorted(called)}, expected {sorted(expected)}"
    assert (state.T is not None) is has_T
    assert ("thermal" in solver.dt_limits) is has_T
    if WALL_PASS <= called:  # the wall pass extrapolates u^ and, only with heat, T
        assert sum(n == "walls.extrapolate" for n, _, _ in recorder) == (2 if has_T else 1)


def test_scene_without_walls_or_heat_has_no_such_work(recorder, state_and_list):
    state, nbrs = state_and_list
    jax.make_jaxpr(_solver(sph.Effects()).step_fn)(state, nbrs, 1)
    called = {n for n, _, _ in recorder}
    assert not called & (WALL_PASS | {"walls.extrapolate", "heat.temperature_rate"})
    assert state.T is None and "T" not in state.field_names()


def test_gravity_adds_exactly_g_to_every_acceleration():
    """What an added effect contributes, not only that the step grew: with gravity g and nothing else
    changed, du/dt differs by g exactly (a wrong sign or factor fails)."""
    g = (0.3, -0.7)
    base = _solver(sph.Effects()).init_fn()[0]
    heavy = _solver(sph.Effects(gravity=g)).init_fn()[0]
    np.testing.assert_allclose(np.asarray(heavy.dudt - base.dudt), np.broadcast_to(g, base.dudt.shape), atol=1e-12)


def test_tvf_background_pressure_pushes_a_displaced_particle_back():
    """Adami 2013 eq. 13 on a lattice with one particle moved off its site by 0.2 dx: the background
    pressure accelerates its transport velocity back toward the site (dv/dt . displacement < 0), and
    only the TVF step has that term (standard SPH keeps dv/dt = 0)."""
    sc = tgv.scene(DX, MAT, sph.Effects(tvf=True))
    r = sc.r.copy()
    k = len(r) // 2 + 3
    shift = np.array([0.2 * DX, 0.1 * DX])
    r[k] += shift
    moved = tgv.scene(DX, MAT, sph.Effects(tvf=True), r=r)
    state = sph.build_solver(moved, sph.Numerics()).init_fn()[0]
    dvdt = np.asarray(state.dvdt)
    assert float(dvdt[k] @ shift) < 0
    d = r - r[k]
    far = np.linalg.norm(d - np.round(d), axis=1) > 7 * DX   # minimum image in the unit box     # beyond two supports (its neighbours' densities changed)
    assert np.abs(dvdt[far]).max() < 1e-9 * np.abs(dvdt[k]).max()   # a lattice away from it feels nothing
    plain = sph.build_solver(tgv.scene(DX, MAT, sph.Effects(), r=r), sph.Numerics()).init_fn()[0]
    assert float(jnp.max(jnp.abs(plain.dvdt))) == 0.0
