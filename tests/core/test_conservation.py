"""Full-solver conservation in a periodic box: linear momentum to round-off, mass exactly.

A jittered lattice with random velocities (non-zero net momentum) is advanced 50 steps with the
complete step (neighbour updates, EoS, integration). Pair forces are antisymmetric and the box has
no walls or body force, so sum_i m_i u_i must stay at its initial value up to accumulated
round-off (~ steps x machine epsilon relative to sum_i m_i |u_i|).
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import rollout
from sph_test_helpers import jittered_lattice, momentum, periodic_scene

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

N_STEPS = 50
EFFECTS = {
    "standard": sph.Effects(),
    "tvf": sph.Effects(tvf=True),
    "riemann": sph.Effects(riemann=True, density_evolution=True),
    "continuity": sph.Effects(density_evolution=True, density_reinit_every=10),
}


@pytest.mark.parametrize("name", list(EFFECTS))
def test_momentum_and_mass_conserved(name):
    dx = 0.05
    r = jittered_lattice(dx, 0.1, seed=21)
    rng = np.random.default_rng(22)
    u = 0.3 * rng.normal(size=r.shape) + np.array([0.2, -0.1])  # net drift: P(0) != 0
    scene = periodic_scene(dx, r, u, EFFECTS[name], sph.Material(eta=0.005, u_ref=1.0))
    solver = sph.build_solver(scene, sph.Numerics(p_bg_factor=0.05))
    state0, nbrs = solver.init_fn()
    chunk = jax.jit(rollout.make_chunk(solver.step_fn, N_STEPS))
    state, nbrs, reallocs = rollout.advance(chunk, solver.neighbors, state0, nbrs, 0, N_STEPS)

    assert bool(jnp.all(jnp.isfinite(state.u))) and bool(jnp.all(jnp.isfinite(state.rho)))
    # the particles really moved and interacted (otherwise conservation would be trivial)
    assert float(jnp.max(jnp.abs(state.u - state0.u))) > 1e-3
    p0, p1 = np.asarray(momentum(state0)), np.asarray(momentum(state))
    scale = float(jnp.sum(state0.mass * jnp.linalg.norm(state0.u, axis=1)))
    assert np.max(np.abs(p1 - p0)) < 1e-12 * scale, f"momentum drift {p1 - p0} (P0 = {p0})"
    # mass is carried by particles and never changes
    np.testing.assert_array_equal(np.asarray(state.mass), np.asarray(state0.mass))
    assert float(jnp.sum(state.mass)) == pytest.approx(1.0 * 1.0 * 1.0, rel=1e-12)  # rho_ref x |box|
