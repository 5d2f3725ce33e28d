"""Configuration validation: every rejected value fails with sph.ConfigError naming the key path."""
from dataclasses import dataclass, field

import pytest

import sph
from sph.cases import tgv
from lab.configtools import from_mapping


@dataclass(frozen=True)
class Run:
    """A nested config as an experiment would declare it."""

    material: sph.Material = field(default_factory=sph.Material)
    effects: sph.Effects = field(default_factory=sph.Effects)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)


def _raises(key, fn, *args, **kwargs):
    with pytest.raises(sph.ConfigError) as exc:
        fn(*args, **kwargs)
    assert key in str(exc.value), f"message {str(exc.value)!r} does not name {key!r}"
    return str(exc.value)


def test_config_error_is_a_value_error():
    assert issubclass(sph.ConfigError, ValueError)


def test_valid_mapping_round_trips():
    num = from_mapping(sph.Numerics, {"cfl": 0.2, "kernel": "wendland_c4", "dt": None, "h_factor": 1})
    assert num == sph.Numerics(cfl=0.2, kernel="wendland_c4", h_factor=1.0)
    fx = from_mapping(sph.Effects, {"gravity": [0, -9.81], "tvf": True})
    assert fx.gravity == (0.0, -9.81) and fx.tvf


def test_unknown_key_is_named():
    _raises("cfll", from_mapping, sph.Numerics, {"cfll": 0.2})


@pytest.mark.parametrize("cls,key,value", [
    (sph.Numerics, "cfl", "high"),
    (sph.Numerics, "kernel", 3),
    (sph.Numerics, "dt", "small"),
    (sph.Material, "eta", True),   # a bool is not a number
    (sph.Effects, "tvf", "yes"),
    (sph.Effects, "density_reinit_every", 2.5),
    (sph.Effects, "gravity", 9.81),
    (sph.Effects, "gravity", [0.0, "down"]),
])
def test_wrong_type_is_named(cls, key, value):
    _raises(key, from_mapping, cls, {key: value})


@pytest.mark.parametrize("data,path", [
    ({"numerics": {"cfll": 0.2}}, "numerics.cfll"),
    ({"numerics": {"cfl": "high"}}, "numerics.cfl"),
    ({"numerics": {"cfl": 1.5}}, "numerics.cfl"),            # value check in __post_init__
    ({"material": {"eta": -1.0}}, "material.eta"),
    ({"effects": {"gravity": [0.0, "down"]}}, "effects.gravity"),
    ({"effects": {"riemann": True}}, "density_evolution"),
    ({"numerics": [1, 2]}, "numerics"),                      # not a mapping
    ({"solver": {}}, "solver"),                              # unknown section
])
def test_nested_configs_name_the_path(data, path):
    _raises(path, from_mapping, Run, data)


def test_riemann_requires_density_evolution():
    _raises("density_evolution", sph.Effects, riemann=True)
    assert sph.Effects(riemann=True, density_evolution=True).riemann


@pytest.mark.parametrize("kwargs,key", [
    ({"dtype": "float16"}, "dtype"),
    ({"dtype": "double"}, "dtype"),
    ({"kernel": "gaussian"}, "kernel"),
    ({"kernel": "Quintic"}, "kernel"),
    ({"cfl": 0.0}, "cfl"),
    ({"h_factor": -1.0}, "h_factor"),
    ({"capacity_multiplier": 0.5}, "capacity_multiplier"),
])
def test_bad_numerics_values(kwargs, key):
    msg = _raises("numerics." + key, sph.Numerics, **kwargs)
    assert repr(next(iter(kwargs.values()))) in msg or str(next(iter(kwargs.values()))) in msg


def test_bad_dtype_and_kernel_through_mapping():
    _raises("numerics.dtype", from_mapping, Run, {"numerics": {"dtype": "float16"}})
    _raises("numerics.kernel", from_mapping, Run, {"numerics": {"kernel": "cubic"}})


@pytest.mark.parametrize("gravity", [(0.0, 0.0, -9.81), (-9.81,)])
def test_gravity_with_wrong_dimension_fails_at_build(gravity):
    scene = tgv.scene(0.125, sph.Material(), sph.Effects(gravity=gravity))  # 2D scene
    msg = _raises("effects.gravity", sph.build_solver, scene)
    assert str(len(gravity)) in msg


def test_gravity_with_right_dimension_builds():
    solver = sph.build_solver(tgv.scene(0.125, sph.Material(), sph.Effects(gravity=(0.0, -1.0))))
    assert "body_force" in solver.dt_limits
