"""The step as an ordered pass list (sph.registry.PASSES, sph.passes): each scene gets exactly the
passes its effects declare, in the registry's order; a pass writes only what it declares; a term
that reads a field its pass does not give it fails naming the field; state_at runs the same list
without the passes that advance in time."""
import dataclasses

import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import registry
from sph.cases import channel, ldc, tank, tgv
from sph.constants import derive
from sph.fields import Fields
from sph.passes import Context, run
from sph.views import MissingField

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

MAT = sph.Material(eta=0.01)
HOT = sph.Material(eta=0.01, kappa=0.1, c_p=1.0)
SCENES = {
    "tgv_sph": (lambda: tgv.scene(0.1, MAT, sph.Effects()), ["DensityPass", "PressurePass", "ForcePass"]),
    "ldc_tvf": (lambda: ldc.setup(0.1, re=100, method="tvf")[0], ["DensityPass", "PressurePass", "WallPass", "ForcePass"]),
    "dam_break": (lambda: tank.scene(0.1, MAT, tank.DAM_BREAK_EFFECTS, width=0.5, height=0.5, tank_length=1.0,
                                     tank_height=1.0),
                  ["DensityPass", "ReinitPass", "PressurePass", "WallPass", "ForcePass"]),
    "heated_channel": (lambda: channel.scene(0.05, HOT, sph.Effects(walls="no_slip", heat=True, gravity=(1.0, 0.0))),
                       ["DensityPass", "PressurePass", "WallPass", "ForcePass", "HeatPass"]),
}


def _solver(name):
    return sph.build_solver(SCENES[name][0](), sph.Numerics())


@pytest.mark.parametrize("name", SCENES)
def test_a_scene_gets_exactly_its_passes_in_registry_order(name):
    solver = _solver(name)
    got = [type(p).__name__ for p in solver.passes]
    assert got == SCENES[name][1]
    order = [cls.__name__ for cls in registry.PASSES]
    assert got == sorted(got, key=order.index)


@pytest.mark.parametrize("name", SCENES)
def test_every_pass_writes_only_what_it_declares(name):
    """Run each pass of one step on the state after a few steps; every field it does not declare in
    `writes` comes out identical (the same array)."""
    solver = _solver(name)
    state, nbrs = solver.init_fn()
    for k in range(1, 4):
        state, nbrs = solver.step_fn(state, nbrs, k)
    ctx = Context.of(solver.scene, derive(solver.scene, solver.numerics))
    f = Fields.of(state)
    for p in solver.passes:
        g = p(f, ctx, nbrs.idx, 20)       # step 20: the re-initialization pass acts
        for field in dataclasses.fields(Fields):
            before, after = getattr(f, field.name), getattr(g, field.name)
            if field.name not in p.writes:
                assert after is before, f"{type(p).__name__} wrote {field.name} without declaring it"
        assert any(getattr(g, w) is not getattr(f, w) for w in p.writes), f"{type(p).__name__} wrote nothing"
        f = g


def test_a_term_reading_an_undeclared_field_fails_naming_it():
    solver = _solver("tgv_sph")
    state, nbrs = solver.init_fn()
    ctx = Context.of(solver.scene, derive(solver.scene, solver.numerics))

    class ReadsRhoUndeclared:
        reads = ("r", "mass")

        def __call__(self, pp, i, j):
            return i.mass * j.rho

    with pytest.raises(MissingField, match="'rho'"):
        ctx.sweep(ReadsRhoUndeclared(), nbrs.idx, Fields.of(state), ReadsRhoUndeclared.reads)


def test_state_at_runs_the_at_rest_passes_of_the_same_list():
    """state_at = the passes that evaluate (not advance) the state, over the same list: on the
    initial fields it equals running them by hand; the continuity, re-initialization and heat passes
    are not among them, summation is."""
    solver = _solver("dam_break")
    at_rest = [type(p).__name__ for p in solver.passes if p.at_rest]
    assert at_rest == ["PressurePass", "WallPass", "ForcePass"]      # evolved density: starts at rho_ref
    assert [p.at_rest for p in _solver("tgv_sph").passes][0] is True  # summation density is evaluated
    state, nbrs = solver.init_fn()
    sc = solver.scene
    ctx = Context.of(sc, derive(sc, solver.numerics))
    zeros = jnp.zeros_like(state.u)
    f = Fields(r=state.r, u=state.u, v=state.v, rho=jnp.full((sc.n,), sc.material.rho_ref), p=jnp.zeros(sc.n),
               mass=state.mass, tag=state.tag, dudt=zeros, dvdt=zeros)
    by_hand = run([p for p in solver.passes if p.at_rest], f, ctx, nbrs.idx, 0).state()
    for name in state.field_names():   # init_fn's is jitted, this one not: equal to round-off
        want = np.asarray(getattr(state, name))
        np.testing.assert_allclose(np.asarray(getattr(by_hand, name)), want, rtol=1e-12,
                                   atol=1e-12 * max(np.abs(want).max(), 1.0), err_msg=name)


def test_effect_names_are_derived_from_the_fields():
    fx = sph.Effects(riemann=True, density_evolution=True, density_reinit_every=20, gravity=(0.0, -1.0),
                     walls="free_slip", artificial_viscosity=0.1, surface_tension=0.5)
    assert fx.names() == ["riemann", "density_evolution", "density_reinit_every=20", "gravity", "walls=free_slip",
                          "artificial_viscosity=0.1", "surface_tension=0.5"]
    assert sph.Effects().names() == []
