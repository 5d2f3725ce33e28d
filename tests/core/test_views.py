"""Particle i and its neighbours j as a term reads them (sph.views): own rows (B, 1), gathered
neighbour rows (B, K), vectors as PVecs, and a missing field named."""
import jax.numpy as jnp
import numpy as np
import pytest

from sph.views import MissingField, Nbr, Own, Particles, rows


def test_own_rows_and_gathered_neighbours():
    rho = jnp.arange(6.0)
    r = jnp.arange(12.0).reshape(6, 2)
    cols = Particles(rho=rho, r=r).columns()
    i = Own(cols, start=2, size=3)
    np.testing.assert_array_equal(np.asarray(i.rho)[:, 0], [2.0, 3.0, 4.0])
    assert i.rho.shape == (3, 1) and len(i.r) == 2
    np.testing.assert_array_equal(np.asarray(i.r.c[1])[:, 0], [5.0, 7.0, 9.0])
    j = Nbr(cols, jnp.asarray([[0, 5], [1, 1], [3, 2]]))
    np.testing.assert_array_equal(np.asarray(j.rho), [[0.0, 5.0], [1.0, 1.0], [3.0, 2.0]])
    np.testing.assert_array_equal(np.asarray(rows(i.r)), np.asarray(r[2:5]))
    assert rows(i.rho).shape == (3,)


def test_reading_a_field_the_pass_does_not_give_names_it():
    i = Own(Particles(rho=jnp.ones(3)).columns())
    with pytest.raises(MissingField, match="'T'"):
        i.T
