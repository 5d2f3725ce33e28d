"""A pass in blocks of rows (sph.blocks): every row once, in order, whatever the block size; the
blocked result equals the one-block result (the pair sums of a summation density over a jittered
lattice)."""
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import blocks
from sph.cases import tgv
from sph.density import Summation

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)


@pytest.mark.parametrize("n,k", [(6400, 50), (1000, 231), (7, 3)])
def test_block_rows_even_out_and_cover_the_rows(n, k, monkeypatch):
    b = blocks.block_rows(n, k)
    assert 1 <= b <= n
    target = max(1, blocks.BLOCK_PAIRS // k)
    assert b <= max(target, 1) or b == n
    assert -(-n // b) == -(-n // min(target, n))   # as few blocks as the target allows, evened out
    monkeypatch.setattr(blocks, "BLOCK_PAIRS", 5 * k)            # force several blocks
    idx = jnp.arange(n * k, dtype=jnp.int32).reshape(n, k)
    out = blocks.over_rows(lambda start, size, rows: rows[:, :1], idx)
    np.testing.assert_array_equal(np.asarray(out)[:, 0], np.arange(n) * k)   # each row once, in order


def test_blocked_pass_equals_one_block(monkeypatch):
    r = tgv.scene(0.05, sph.Material(), sph.Effects()).r
    r = np.mod(r + np.random.default_rng(1).normal(scale=0.0025, size=r.shape), 1.0)
    sc = tgv.scene(0.05, sph.Material(), sph.Effects(), r=r)
    solver = sph.build_solver(sc, sph.Numerics())
    _, nbrs = solver.init_fn()
    mass = jnp.asarray(sc.particle_mass)
    term = Summation(float(solver.kernel.w(0.0)))
    whole = solver.sweep_fn(term, nbrs, r=jnp.asarray(sc.r), mass=mass)
    monkeypatch.setattr(blocks, "BLOCK_PAIRS", 37 * nbrs.idx.shape[1])    # 11 blocks, the last one shifted
    blocked = solver.sweep_fn(term, nbrs, r=jnp.asarray(sc.r), mass=mass)
    np.testing.assert_allclose(np.asarray(blocked), np.asarray(whole), rtol=1e-14)
    assert abs(float(np.mean(whole)) - 1.0) < 0.01      # and it is a density near rho_ref (jitter 0.05 dx)
