"""Issue 23, class 2 / 4 / 5 at the core: inputs checked against the resolution before a step, and
suggestions that pass.

Every case asserts the exact behaviour: a `ConfigError` whose one-line message names the bad value
(and, for a suggested bound, that the suggested value itself builds and starts).
"""
import dataclasses
import re

import numpy as np
import pytest

import sph
from sph.cases import ldc, tgv

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

MAT = sph.Material(eta=0.01)


@pytest.fixture(scope="module")
def tgv_scene():
    return tgv.scene(0.05, MAT, sph.Effects())


def _start(scene, numerics=sph.Numerics()):
    return sph.build_solver(scene, numerics).init_fn()


def test_particles_made_for_another_dx_are_refused(tgv_scene):
    """A scene whose dx is half its particles' spacing (a cache of another resolution) would run at a
    quarter of the density; it is refused before the first step, naming both spacings."""
    with pytest.raises(sph.ConfigError, match=r"spacing \(median nearest-neighbour distance 0\.05\) is 2 dx for "
                                              r"scene\.dx = 0\.025.*density near 0\.25 rho_ref"):
        _start(dataclasses.replace(tgv_scene, dx=0.025))


def test_jittered_and_relaxed_spacings_pass(tgv_scene):
    """A lattice jittered by 0.2 dx (nearest neighbours down to ~0.6 dx) is a legitimate start."""
    from sph.lattice import jitter

    r = jitter(tgv_scene.r, 0.2 * tgv_scene.dx, seed=3, box=tgv_scene.domain.box)
    state, _ = _start(dataclasses.replace(tgv_scene, r=r))
    assert np.all(np.isfinite(np.asarray(state.dudt)))


def test_coincident_particles_are_named(tgv_scene):
    r = tgv_scene.r.copy()
    r[17] = r[16]
    with pytest.raises(sph.ConfigError, match=r"particles 16 and 17 coincide"):
        _start(dataclasses.replace(tgv_scene, r=r))


def test_kernel_support_without_neighbours_names_h_factor(tgv_scene):
    """h = 0.4 dx leaves 4 neighbours in the support (the density error was x7, rc 0, before)."""
    with pytest.raises(sph.ConfigError, match=r"^numerics\.h_factor: 0\.4 gives a kernel support of 1\.2 dx with 4 "):
        _start(tgv_scene, sph.Numerics(h_factor=0.4))


@pytest.mark.parametrize("dx", [0.0, -0.05, float("nan")])
def test_non_positive_dx_through_the_api_is_named(tgv_scene, dx):
    with pytest.raises(sph.ConfigError, match=r"scene tgv2d: dx must be a positive number"):
        dataclasses.replace(tgv_scene, dx=dx)


@pytest.mark.parametrize("dx", [1.0, 0.5, 0.44])
def test_walled_box_suggestion_is_a_value_that_passes(dx):
    """The cavity's box shrinks with dx (wall layers of dx); the suggested dx accounts for it: building
    the cavity at the suggested dx succeeds (before, 0.78 was suggested, then 0.44, then 0.40...)."""
    with pytest.raises(sph.ConfigError) as err:
        sph.build_solver(ldc.scene(dx, MAT, sph.Effects(walls="no_slip")))
    suggested = float(re.search(r"use dx = ([0-9.e-]+) or finer", str(err.value)).group(1))
    assert suggested == pytest.approx(1 / 3, rel=1e-9)
    state, _ = _start(ldc.scene(suggested, MAT, sph.Effects(walls="no_slip")))
    assert state.n > 0
    sph.build_solver(*ldc.setup(suggested, re=100)).init_fn()     # the validated recipe takes it too (1/dx whole)


def test_dam_break_suggestion_keeps_the_columns_whole():
    """The dam break at dx 1 used to suggest dx <= 0.6666, which the column of height 1 refuses (not
    whole spacings); the suggestion is now the coarsest dx dividing the span and the fluid: 0.5."""
    from sph.cases import tank

    def scene(dx):
        return tank.scene(dx, sph.Material(eta=1e-4, u_ref=1.4), tank.DAM_BREAK_EFFECTS, width=2.0, height=1.0,
                          tank_length=5.366, tank_height=2.0)

    with pytest.raises(sph.ConfigError) as err:
        sph.build_solver(scene(1.0), tank.DAM_BREAK_NUMERICS)
    suggested = float(re.search(r"use dx = ([0-9.e-]+) or finer", str(err.value)).group(1))
    assert suggested == 0.5
    state, _ = _start(scene(suggested), tank.DAM_BREAK_NUMERICS)
    assert state.n > 0


def test_periodic_suggestion_is_a_value_that_passes():
    with pytest.raises(sph.ConfigError) as err:
        sph.build_solver(tgv.scene(0.25, MAT, sph.Effects()))
    suggested = float(re.search(r"use dx = ([0-9.e-]+) or finer", str(err.value)).group(1))
    assert suggested == pytest.approx(1 / 6, rel=1e-9)
    _start(tgv.scene(suggested, MAT, sph.Effects()))
