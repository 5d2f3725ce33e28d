"""Body forces (sph.forces): values, vectorization, and their exact contribution to du/dt."""
import dataclasses

import jax
import numpy as np
import pytest

import sph
from sph.cases import tgv
from sph.forces import ConstantForce, ReversePoiseuilleForce

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

DX = 0.05


def test_reverse_poiseuille_force_field():
    """+g in x below the split, -g above, nothing in y (Fatehi & Manzari 2011 driving force)."""
    r = np.array([[0.3, 0.2], [0.7, 0.99], [0.1, 1.0], [0.5, 1.7]])
    f = np.asarray(ReversePoiseuilleForce(g=1.5, split=1.0)(jax.numpy.asarray(r)))
    np.testing.assert_array_equal(f, [[1.5, 0.0], [1.5, 0.0], [-1.5, 0.0], [-1.5, 0.0]])
    assert ReversePoiseuilleForce(g=-2.0, split=1.0).g_max == 2.0
    assert ConstantForce((0.0, -3.0, 4.0)).g_max == pytest.approx(5.0)


def test_space_dependent_force_enters_the_acceleration_exactly():
    """du/dt with a body force minus du/dt without it equals the force at each particle's position
    (a 1 x 2 periodic box, split at y = 1), and the force sets the body-force time-step limit."""
    mat = sph.Material(eta=0.01)
    r = sph.lattice.cartesian([0.0, 0.0], [1.0, 2.0], DX)
    base = tgv.scene(DX, mat, sph.Effects())
    base = dataclasses.replace(base, r=r, u=np.zeros_like(r), tag=np.zeros(len(r), np.int32),
                               domain=sph.Domain(box=(1.0, 2.0), periodic=(True, True)))
    force = ReversePoiseuilleForce(g=1.0, split=1.0)
    num = sph.Numerics(dt=1e-3)
    s0 = sph.build_solver(base, num)
    s1 = sph.build_solver(dataclasses.replace(base, body_force=force), num)
    st0, _ = s0.init_fn()
    st1, _ = s1.init_fn()
    np.testing.assert_allclose(np.asarray(st1.dudt - st0.dudt), np.asarray(force(st0.r)), atol=1e-10)
    assert s1.dt_limits["body_force"] == pytest.approx(0.25 * np.sqrt(DX / 1.0))
    assert "body_force" not in s0.dt_limits
