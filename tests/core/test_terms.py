"""The step's term interface: a new effect is a term object, added without touching the solver.

A toy linear damping du/dt = -gamma u is added through `build_solver(..., extra_terms=...)` (the
public term interface, `sph.terms`) and checked against the exact change it must make to one step:
with a fixed dt, positions and densities of the next step are unchanged (the damping acts on the
new acceleration only) and du/dt differs by exactly -gamma u.
"""
from dataclasses import dataclass

import jax
import numpy as np
import pytest

import sph
from sph.cases import tgv
from sph.rates import Rates

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)


@dataclass(frozen=True)
class Damping:
    """du_i/dt = -gamma u_i: a force-pass term that reads only particle i."""

    gamma: float

    def __call__(self, pairs, i, j):
        return Rates(dudt=-self.gamma * i.u)


def test_toy_damping_term_changes_one_step_exactly():
    sph.precision.enable_x64()
    scene = tgv.scene(0.05, sph.Material(eta=0.01), sph.Effects())
    num = sph.Numerics(dtype="float64", dt=1e-3)
    plain = sph.build_solver(scene, num)
    damped = sph.build_solver(scene, num, extra_terms=(Damping(0.7),))
    state, nbrs = plain.init_fn()
    s0, _ = jax.jit(plain.step_fn)(state, nbrs, 1)
    s1, _ = jax.jit(damped.step_fn)(state, nbrs, 1)
    np.testing.assert_array_equal(np.asarray(s1.r), np.asarray(s0.r))
    np.testing.assert_array_equal(np.asarray(s1.rho), np.asarray(s0.rho))
    scale = float(np.abs(np.asarray(s0.dudt)).max())
    np.testing.assert_allclose(np.asarray(s1.dudt - s0.dudt), -0.7 * np.asarray(s0.u), rtol=0, atol=1e-12 * scale)
    assert float(np.abs(np.asarray(s0.u)).max()) > 0.1  # the damping is not trivially zero


def test_a_term_reading_a_field_the_pass_lacks_names_it():
    """A force term that reads the temperature in a scene without heat fails at trace time with a
    message naming the field."""
    @dataclass(frozen=True)
    class NeedsT:
        def __call__(self, pairs, i, j):
            return Rates(dTdt=i.T)

    scene = tgv.scene(0.1, sph.Material(eta=0.01), sph.Effects())
    solver = sph.build_solver(scene, sph.Numerics(dtype="float32"), extra_terms=(NeedsT(),))
    try:
        solver.init_fn()
    except AttributeError as e:
        assert "'T'" in str(e) and "not provided" in str(e)
    else:
        raise AssertionError("a term reading a missing field must fail")
