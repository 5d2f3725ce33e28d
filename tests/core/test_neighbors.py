"""Neighbour search: exact pair sets against brute force, and overflow detection with recovery.

* The Dense list of either backend (sph.cell_list's "cell_sort", jax-md's "jax_md") holds exactly
  the pairs i != j with |r_ij| < cutoff + skin (minimum image in periodic dimensions only),
  compared with an O(N^2) numpy search.
* Between rebuilds (every particle moved < skin / 2) the old list still holds every pair within the
  cutoff (the Verlet-skin guarantee).
* A list that is too small is detected, the offending step is not taken, the list is re-allocated
  and the run continues: the result equals a run that had ample capacity from the start.
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import rollout
from sph.cases import tgv
from sph.domain import Domain
from sph.neighbors import make_neighbor_search
from sph_test_helpers import brute_force_neighbors, jittered_lattice, listed_pairs, periodic_scene

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

CUTOFF, SKIN = 0.15, 0.025


def _brute_force_pairs(r, radius, domain):
    return listed_pairs(brute_force_neighbors(r, radius, domain.box, domain.periodic))


DOMAINS = {
    "periodic": Domain(box=(1.0, 1.0), periodic=(True, True)),
    "periodic-x-only": Domain(box=(1.0, 0.6), periodic=(True, False)),
}


def _random_list(name, backend, seed, lo=0.0, hi=1.0, n=300):
    """(domain, rng, positions, search, list): n particles uniform in [lo, hi] times the box of
    DOMAINS[name], and their list from `backend`."""
    domain = DOMAINS[name]
    rng = np.random.default_rng(seed)
    r = rng.uniform(lo, hi, size=(n, 2)) * np.asarray(domain.box)
    search = make_neighbor_search(domain, CUTOFF, SKIN, backend=backend)
    return domain, rng, r, search, search.allocate(jnp.asarray(r))


@pytest.mark.parametrize("backend", ["cell_sort", "jax_md"])
@pytest.mark.parametrize("name", list(DOMAINS))
def test_list_equals_brute_force_pairs(name, backend):
    domain, _, r, search, nbrs = _random_list(name, backend, 51)
    assert not bool(nbrs.did_buffer_overflow)
    listed = listed_pairs(nbrs.idx)  # no duplicate, no self pair
    expected = _brute_force_pairs(r, CUTOFF + SKIN, domain)
    assert listed == expected, (f"missing {sorted(expected - listed)[:5]}, "
                                f"extra {sorted(listed - expected)[:5]}")
    if backend == "jax_md":
        assert nbrs.cell_list_fn is not None, "meant to exercise the cell-list path"
    else:
        assert min(search.impl.n_cells) >= 3, "meant to exercise the 3^dim neighbour-cell path"
    # the list is symmetric; periodic dimensions use the images, non-periodic ones never do
    assert all((j, i) in listed for i, j in listed)
    ii, jj = np.array(sorted(listed)).T
    plain = np.abs(r[ii] - r[jj])
    for d, periodic in enumerate(domain.periodic):
        if periodic:
            assert np.any(plain[:, d] > CUTOFF + SKIN), f"no pair across the periodic boundary in dim {d}"
        else:
            assert np.all(plain[:, d] < CUTOFF + SKIN), f"a pair wraps around the non-periodic dim {d}"


@pytest.mark.parametrize("backend", ["cell_sort", "jax_md"])
@pytest.mark.parametrize("name", list(DOMAINS))
def test_verlet_skin_keeps_all_pairs_within_cutoff(name, backend):
    domain, rng, r, search, nbrs = _random_list(name, backend, 52, 0.1, 0.9)  # non-periodic moves stay inside
    box = np.asarray(domain.box)

    # small moves (< skin / 2): no rebuild, but every pair within the cutoff is still listed
    step = rng.normal(size=r.shape)
    step *= 0.49 * SKIN / np.max(np.linalg.norm(step, axis=1))
    r1 = np.where(domain.periodic, np.mod(r + step, box), r + step)
    nbrs1 = search.update(jnp.asarray(r1), nbrs)
    assert not bool(nbrs1.did_buffer_overflow)
    np.testing.assert_array_equal(np.asarray(nbrs1.idx), np.asarray(nbrs.idx))  # not rebuilt
    assert _brute_force_pairs(r1, CUTOFF, domain) <= listed_pairs(nbrs1.idx)

    # a larger move triggers a rebuild, which is again exact for cutoff + skin
    step2 = np.zeros_like(r)
    step2[7] = [0.8 * SKIN, 0.0]
    r2 = np.where(domain.periodic, np.mod(r1 + step2, box), r1 + step2)
    nbrs2 = search.update(jnp.asarray(r2), nbrs1)
    assert not bool(nbrs2.did_buffer_overflow)
    np.testing.assert_array_equal(np.asarray(nbrs2.reference_position), r2)  # rebuilt at r2
    assert listed_pairs(nbrs2.idx) == _brute_force_pairs(r2, CUTOFF + SKIN, domain)


def _assert_states_close(a, b, rtol=1e-12):
    """Field-by-field agreement relative to each field's magnitude (positions by minimum image)."""
    for f in ("r", "u", "v", "rho", "p", "mass", "dudt", "dvdt"):
        x, y = np.asarray(getattr(a, f)), np.asarray(getattr(b, f))
        d = x - y
        if f == "r":
            d = d - np.round(d)  # unit periodic box
        scale = max(float(np.max(np.abs(y))), 1e-300)
        assert np.max(np.abs(d)) <= rtol * scale, f"{f}: max difference {np.max(np.abs(d)):.3g} (scale {scale:.3g})"


N_STEPS = 50
DX = 0.05


@pytest.fixture(scope="module")
def crowded_run():
    """A strongly jittered TGV state (crowded particles need more neighbour slots than a lattice),
    its solver, one jitted chunk, and the reference rollout with ample capacity from the start."""
    r = jittered_lattice(DX, 0.2, seed=53)
    solver = sph.build_solver(periodic_scene(DX, r, tgv.velocity(r), sph.Effects(tvf=True),
                                             sph.Material(eta=0.01)))
    state0, nbrs0 = solver.init_fn()  # the default list (capacity_multiplier 1.25) is ample here
    chunk = jax.jit(rollout.make_chunk(solver.step_fn, N_STEPS))
    reference, _, reallocs = rollout.advance(chunk, solver.neighbors, state0, nbrs0, 0, N_STEPS)
    assert reallocs == 0, "the reference run was meant to have ample capacity"
    return solver, state0, chunk, reference


def _tight_search(solver):
    """The solver's search, but allocating with no spare capacity (capacity_multiplier = 1)."""
    return make_neighbor_search(solver.scene.domain, solver.neighbors.cutoff, solver.neighbors.skin, 1.0)


def test_list_allocated_on_sparse_configuration_recovers_on_dense_state(crowded_run):
    """Allocate a tight list on the perfect lattice (the most uniform arrangement: fewest neighbours
    per particle), then advance the crowded state with it."""
    solver, state0, chunk, reference = crowded_run
    lattice_r = jnp.asarray(tgv.scene(DX, sph.Material(), sph.Effects()).r)
    sparse = _tight_search(solver).allocate(lattice_r)
    needed = brute_force_neighbors(np.asarray(state0.r), solver.neighbors.cutoff + solver.neighbors.skin).shape[1]
    assert sparse.idx.shape[1] < needed  # the premise: the list is too small for the dense state
    # the first step overflows, is not taken, and the chunk stops there with the state untouched
    state, _, n_done, overflow = chunk(state0, sparse, 0, N_STEPS)
    assert bool(overflow) and int(n_done) == 0
    _assert_states_close(state, state0, rtol=0.0)
    state, nbrs, reallocs = rollout.advance(chunk, solver.neighbors, state0, sparse, 0, N_STEPS)
    assert reallocs >= 1
    assert not bool(nbrs.did_buffer_overflow)
    _assert_states_close(state, reference)


def test_overflow_during_run_is_recovered_exactly(crowded_run):
    """A list that is exactly full at t = 0 overflows as soon as the flow crowds any particle further;
    the overflowing step is redone with a re-allocated list."""
    solver, state0, chunk, reference = crowded_run
    tight = _tight_search(solver).allocate(state0.r)
    _, _, n_done, overflow = chunk(state0, tight, 0, N_STEPS)
    assert bool(overflow) and 0 < int(n_done) < N_STEPS  # overflows mid-run, not at the first step
    state, nbrs, reallocs = rollout.advance(chunk, solver.neighbors, state0, tight, 0, N_STEPS)
    assert reallocs >= 1
    assert nbrs.idx.shape[1] > tight.idx.shape[1]
    _assert_states_close(state, reference)


@pytest.mark.parametrize("kernel,h_factor,support", [("quintic", 1.0, 3.0), ("wendland_c4", 1.3, 2.0)])
def test_solver_searches_the_kernel_support_plus_skin(kernel, h_factor, support):
    dx = 0.05
    num = sph.Numerics(kernel=kernel, h_factor=h_factor, skin_factor=0.4)
    solver = sph.build_solver(tgv.scene(dx, sph.Material(), sph.Effects()), num)
    assert solver.neighbors.cutoff == pytest.approx(support * h_factor * dx, rel=1e-12)
    assert solver.neighbors.skin == pytest.approx(0.4 * dx, rel=1e-12)
