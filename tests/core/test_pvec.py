"""Pair vectors as their components (sph.pvec) against numpy's (..., dim) arrays."""
import jax.numpy as jnp
import numpy as np

from sph.pvec import PVec, dot, where

RNG = np.random.default_rng(3)
A, B = RNG.normal(size=(4, 5, 3)), RNG.normal(size=(4, 5, 3))


def pv(x):
    return PVec(jnp.asarray(x[..., a]) for a in range(x.shape[-1]))


def test_arithmetic_dot_where_and_stack_match_numpy():
    a, b, s = pv(A), pv(B), jnp.asarray(RNG.normal(size=(4, 5)))
    np.testing.assert_allclose((a + b).stack(), A + B)
    np.testing.assert_allclose((a - b).stack(), A - B)
    np.testing.assert_allclose((a * s).stack(), A * np.asarray(s)[..., None])
    np.testing.assert_allclose((2.0 * a - b / 4.0).stack(), 2 * A - B / 4)
    np.testing.assert_allclose((-a).stack(), -A)
    np.testing.assert_allclose(dot(a, b), np.sum(A * B, axis=-1), rtol=1e-12)
    cond = np.asarray(s) > 0
    np.testing.assert_allclose(where(jnp.asarray(cond), a, b).stack(), np.where(cond[..., None], A, B))


def test_per_particle_components_stack_to_rows():
    own = PVec(jnp.asarray(A[:, :1, a]) for a in range(3))   # (B, 1) components, as a block's own rows
    assert own.stack().shape == (4, 3)
    np.testing.assert_allclose(own.stack(), A[:, 0, :])
