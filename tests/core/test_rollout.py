"""`sph.rollout.advance` over more steps than its chunk holds: it calls the chunk again (no false
`NeighborOverflow` at step length + 1) and lands on the same state as one long chunk; and
`sph.simulate.states_at`, the states at chosen times built on it."""
import jax
import numpy as np
import pytest

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


def test_states_at_chosen_times_equal_the_step_by_step_states_and_refuse_others():
    """sph.simulate.states_at: the state at each requested time, fluid rows only by default (the
    cavity's walls left out); a time between steps is refused naming the nearest, not skipped."""
    from sph import simulate
    from sph.cases import ldc

    sc, nm = ldc.setup(0.1, re=100)
    solver = sph.build_solver(sc, nm)
    state, nbrs = solver.init_fn()
    dt = solver.dt
    got = simulate.states_at(solver, state, nbrs, [12 * dt, 0.0, 5 * dt])
    step = jax.jit(solver.step_fn)
    s, nb, by_step = state, nbrs, {0: state}
    for k in range(1, 13):
        s, nb = step(s, nb, k)
        by_step[k] = s
    fluid = sc.fluid_mask
    for g, k in zip(got, (12, 0, 5)):
        assert g.r.shape == (int(fluid.sum()), 2)
        np.testing.assert_allclose(np.asarray(g.u), np.asarray(by_step[k].u)[fluid], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"t = .* is not a whole number of steps .* the nearest are"):
        simulate.states_at(solver, state, nbrs, [2.5 * dt])
