"""Long differentiable rollouts: overflow-safe gradients (`sph.rollout.value_and_grad_rollout`) and
gradients through 200 steps.

Setup: TGV with the transport-velocity formulation, dx = 0.1 (100 particles), lattice jittered by
0.2 dx (crowded particles reshuffle their neighbours), Re = 100, float64, 200 steps (t = 0.45) with
nested gradient checkpointing (14 segments, every step checkpointed inside them: `remat_steps`).
L(r0) = E_kin after 200 steps, differentiated with respect to the initial positions (initial
velocities held fixed).

All tests share one `value_and_grad_rollout` (compiled once per neighbour-list capacity).
"""
import jax
import numpy as np
import pytest

import sph
from sph.cases import tgv
from sph.lattice import cartesian, jitter
from sph.neighbors import make_neighbor_search
from sph.rollout import allocate_covering, make_chunk, size_list, value_and_grad_rollout
from sph_test_helpers import kinetic_energy

DX = 0.1
N_STEPS = 200
SEGMENTS = 14  # ~ sqrt(200)
EPS = 1e-6
EXTRA = 8      # slots of the "ample" list (jax-md extra_capacity), enough for the +-EPS perturbations


@pytest.fixture(scope="module")
def setup():
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], DX), 0.2 * DX, seed=53, box=[1.0, 1.0])
    solver = sph.build_solver(tgv.scene(DX, sph.Material(eta=0.01), sph.Effects(tvf=True), r=r),
                              sph.Numerics(dtype="float64"))
    state0, _ = solver.init_fn()
    vg = value_and_grad_rollout(kinetic_energy, solver, N_STEPS, segments=SEGMENTS, remat_steps=True)
    ample = vg(state0.r, solver.neighbors.allocate(state0.r, extra_capacity=EXTRA))
    return solver, state0, vg, ample


def test_too_small_list_is_reallocated_and_gives_the_ample_gradient(setup):
    """A list with no spare capacity (capacity_multiplier 1.0 at t = 0) overflows as the vortex
    reshuffles the neighbours; the differentiated pass is detected as invalid, the list re-allocated
    and the gradient redone. Same rollout without overflow => same gradient as with an ample list."""
    solver, state0, vg, ample = setup
    assert ample.reallocations == 0  # the reference is valid as given
    tight = make_neighbor_search(solver.scene.domain, solver.neighbors.cutoff, solver.neighbors.skin,
                                 1.0).allocate(state0.r)
    res = vg(state0.r, tight)
    print(f"tight list: {tight.max_occupancy} slots -> {res.nbrs.max_occupancy} after "
          f"{res.reallocations} re-allocation(s); ample list {ample.nbrs.max_occupancy} slots")
    assert res.reallocations >= 1
    assert res.nbrs.max_occupancy > tight.max_occupancy
    assert float(res.value) == pytest.approx(float(ample.value), rel=1e-12)
    g, g_ref = np.asarray(res.grad), np.asarray(ample.grad)
    assert np.max(np.abs(g - g_ref)) <= 1e-10 * np.max(np.abs(g_ref))


def test_forward_sizing_gives_one_list_for_the_whole_rollout(setup):
    """`size_list` with a search that allocates no spare capacity (multiplier 1.0, so no slack can
    hide a wrong argument): the capacity it finds, allocated once at t = 0, runs all 200 steps without
    overflow, although a list allocated at t = 0 without it overflows; with no re-allocations allowed
    it raises."""
    solver, state0, _, _ = setup
    tight = make_neighbor_search(solver.scene.domain, solver.neighbors.cutoff, solver.neighbors.skin, 1.0)
    chunk = jax.jit(make_chunk(solver.step_fn, N_STEPS))
    _, _, n_done, overflow = chunk(state0, tight.allocate(state0.r), 0, N_STEPS)
    assert bool(overflow) and int(n_done) < N_STEPS
    cap, n_reallocs = size_list(solver.step_fn, tight, state0, N_STEPS, chunk=chunk)
    assert n_reallocs >= 1
    nbrs = allocate_covering(tight, state0.r, cap)
    assert nbrs.max_occupancy >= cap[0]
    _, _, n_done, overflow = chunk(state0, nbrs, 0, N_STEPS)
    assert not bool(overflow) and int(n_done) == N_STEPS
    with pytest.raises(RuntimeError, match="overflowed"):
        size_list(solver.step_fn, tight, state0, N_STEPS, max_reallocations=0, chunk=chunk)


def test_gradient_through_200_steps_is_finite_and_matches_finite_differences(setup):
    solver, state0, vg, ample = setup
    g = np.asarray(ample.grad)
    norm = float(np.linalg.norm(g))
    print(f"E_kin(200 steps) = {float(ample.value):.6g}, |dE/dr0| = {norm:.4g}")
    assert np.all(np.isfinite(g))
    # scale: moving the particles by O(dx) changes the (disorder-driven) dissipation by O(1), i.e.
    # L by O(its decay E(0) - L = 0.16), so |dL/dr0| ~ 0.16 / dx = 1.6. Neither blown up nor
    # vanished through 200 steps: within a factor 100 of that (measured 2.0)
    assert 1.6e-2 < norm < 1.6e2
    # periodic box, velocities attached to particles: a uniform shift of all r0 leaves L unchanged,
    # so sum_i dL/dr0_i = 0 (to round-off)
    assert np.max(np.abs(g.sum(axis=0))) < 1e-10 * norm
    rng = np.random.default_rng(7)
    d = rng.normal(size=g.shape)
    d /= np.linalg.norm(d)
    nbrs = ample.nbrs  # the same list for both evaluations, as for the gradient
    lp, lm = vg(state0.r + EPS * d, nbrs), vg(state0.r - EPS * d, nbrs)
    assert lp.reallocations == 0 and lm.reallocations == 0
    fd = (float(lp.value) - float(lm.value)) / (2 * EPS)
    ad = float(np.vdot(g, d))
    print(f"grad . d = {ad:.12g}, central FD = {fd:.12g}, rel. err {abs(ad - fd) / abs(fd):.2e}")
    assert ad == pytest.approx(fd, rel=1e-4)
