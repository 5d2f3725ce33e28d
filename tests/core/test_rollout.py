"""`sph.rollout.advance` over more steps than its chunk holds: it calls the chunk again (no false
`NeighborOverflow` at step length + 1) and lands on the same state as one long chunk."""
import jax
import numpy as np

import sph
from sph import rollout
from sph.cases import tgv


def test_advance_beyond_the_chunk_length_equals_one_long_chunk():
    sc = tgv.scene(0.1, tgv.material(100.0), sph.Effects(tvf=True))
    solver = sph.build_solver(sc, sph.Numerics())
    state, nbrs = solver.init_fn()
    short = jax.jit(rollout.make_chunk(solver.step_fn, 10, guard=solver.guard))
    long = jax.jit(rollout.make_chunk(solver.step_fn, 20, guard=solver.guard))
    a, _, _ = rollout.advance(short, solver.neighbors, state, nbrs, 0, 20)
    b, _, _ = rollout.advance(long, solver.neighbors, state, nbrs, 0, 20)
    for name in a.field_names():
        np.testing.assert_array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name)), err_msg=name)
    assert not np.allclose(np.asarray(a.r), sc.r)   # it moved
