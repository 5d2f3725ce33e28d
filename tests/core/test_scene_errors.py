"""A scene that asks for an effect without what it needs fails at load, naming the missing piece."""
import dataclasses

import numpy as np
import pytest

import sph
from sph.cases import ldc, tank
from lab.configtools import ConfigError, from_mapping
from sph.heat import TemperatureZone

DX = 0.1
MAT = sph.Material(eta=0.01)
HOT = sph.Material(eta=0.01, kappa=1.0, c_p=1.0)
WALLS = sph.Effects(walls="no_slip")


BASE = ldc.scene(DX, MAT, WALLS)


def _cavity(effects=WALLS, material=MAT, **changes):
    """The coarse cavity with some of its fields replaced (validated again on construction)."""
    return dataclasses.replace(BASE, effects=effects, material=material, **changes)


def test_valid_scenes_load():
    s = _cavity(sph.Effects(walls="no_slip", riemann=True, density_evolution=True))
    assert s.wall_mask.sum() > 0 and s.fluid_mask.sum() == 100
    _cavity(sph.Effects(walls="no_slip", heat=True), HOT, T=np.ones(s.n))


@pytest.mark.parametrize("make,needle", [
    (lambda: _cavity(sph.Effects(walls="no_slip", riemann=True, density_evolution=True), normal=None),
     "Riemann walls (effects.riemann) need wall normals: scene.normal is missing"),
    (lambda: _cavity(sph.Effects(walls="free_slip"), normal=None), "free-slip walls"),
    (lambda: _cavity(sph.Effects()), "wall particles but effects.walls is null"),
    (lambda: _cavity(tag=np.where(BASE.tag == sph.MOVING_WALL, sph.MOVING_WALL, sph.FLUID)
                     .astype(np.int32) * 0, u=np.zeros((BASE.n, 2))),
     "effects.walls is 'no_slip' but the scene has no wall particles"),
    (lambda: _cavity(u=np.zeros((BASE.n, 2))), "moving-wall particles (tag MOVING_WALL) have no velocity"),
    (lambda: _cavity(sph.Effects(walls="no_slip", heat=True), MAT, T=np.ones(BASE.n)),
     "effects.heat needs material.kappa"),
    (lambda: _cavity(sph.Effects(walls="no_slip", heat=True), sph.Material(kappa=1.0), T=np.ones(BASE.n)),
     "effects.heat needs material.c_p"),
    (lambda: _cavity(sph.Effects(walls="no_slip", heat=True), HOT), "effects.heat needs an initial temperature scene.T"),
    (lambda: _cavity(WALLS, HOT, T=np.ones(BASE.n)), "carries a temperature but effects.heat is false"),
    (lambda: _cavity(WALLS, HOT, T_zones=(TemperatureZone(0, 0.0, 0.1, 1.0),)), "effects.heat is false"),
])
def test_missing_piece_is_named(make, needle):
    with pytest.raises(ConfigError, match=None) as err:
        make()
    assert needle in str(err.value), str(err.value)


def test_dirichlet_wall_without_temperature():
    base = BASE
    T = np.where(base.fluid_mask, 1.0, np.nan)
    fixed = base.wall_mask.copy()
    with pytest.raises(ConfigError, match=r"Dirichlet \(T_fixed\) particle \d+ has no temperature"):
        _cavity(sph.Effects(walls="no_slip", heat=True), HOT, T=T, T_fixed=fixed)
    # the same temperatures are fine when the walls only extrapolate (no Dirichlet segment)
    _cavity(sph.Effects(walls="no_slip", heat=True), HOT, T=T, T_fixed=np.zeros(base.n, bool))


def test_fixed_wall_with_velocity_and_bad_normals():
    base = BASE
    u = base.u.copy()
    u[np.flatnonzero(base.tag == sph.WALL)[0]] = (0.0, 1.0)
    with pytest.raises(ConfigError, match="fixed wall particles .* must have zero velocity"):
        _cavity(u=u)
    normal = base.normal.copy()
    normal[base.wall_mask] *= 2.0
    with pytest.raises(ConfigError, match="scene.normal of wall particle .* not a unit vector"):
        _cavity(normal=normal)


def test_gravity_and_body_force_together_are_rejected():
    from sph.forces import ReversePoiseuilleForce
    with pytest.raises(ConfigError, match="both effects.gravity and a body_force"):
        _cavity(sph.Effects(walls="no_slip", gravity=(0.0, -1.0)), body_force=ReversePoiseuilleForce(1.0, 0.5))


@pytest.mark.parametrize("data,needle", [
    ({"walls": "noslip"}, "effects.walls: 'noslip' is not one of"),
    ({"artificial_viscosity": -0.1}, "effects.artificial_viscosity: must be >= 0"),
    ({"heat": "yes"}, "effects.heat"),
])
def test_effects_config_errors_name_the_key(data, needle):
    with pytest.raises(ConfigError) as err:
        from_mapping(sph.Effects, data, "effects")
    assert needle in str(err.value)


def test_material_heat_constants_must_be_positive():
    with pytest.raises(ConfigError, match="material.kappa: must be positive"):
        sph.Material(kappa=0.0, c_p=1.0)
    with pytest.raises(ConfigError, match="material.c_p: must be positive"):
        sph.Material(kappa=1.0, c_p=-1.0)


def test_tank_scene_is_closed_and_normals_point_into_the_fluid():
    s = tank.scene(DX, MAT, sph.Effects(walls="no_slip"), width=0.5, height=0.5, tank_length=1.0, tank_height=1.0)
    wall = s.wall_mask
    r, n = s.r[wall], s.normal[wall]
    centre = np.array([0.5, 0.5]) + 3 * DX
    assert np.all(np.sum(n * (centre - r), axis=1) > 0)  # every normal points towards the interior
