"""The sort-based cell list (sph.cell_list) against jax-md's, the reference implementation.

* Pair sets: the set of (i, j) with |r_ij| < cutoff + skin is identical to jax-md's Dense list on
  random and (jittered) lattice inputs, 2D and 3D, periodic, walled and mixed domains, float64 and
  float32; no duplicates, no self pairs.
* Overflow is never silent: particles crowded into one cell (cell capacity) or around one particle
  (neighbour slots) after `allocate` raise `did_buffer_overflow` in the jitted update.
* Verlet skin: below skin / 2 of motion the update returns the list unchanged, above it rebuilds.
* In the solver: a short TGV run and a gradient through `scan_rollout` with backend "cell_sort"
  equal those with "jax_md" to round-off (the lists differ only in the order of the slots, which
  reorders the pair sums).
"""
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph import rollout
from sph.cases import tgv
from sph.domain import Domain
from sph.lattice import cartesian, jitter
from sph.neighbors import make_neighbor_search
from sph_test_helpers import kinetic_energy


def _pairs(idx):
    idx = np.asarray(idx)
    n = idx.shape[0]
    i, k = np.nonzero(idx < n)
    pairs = list(zip(i.tolist(), idx[i, k].tolist()))
    assert len(set(pairs)) == len(pairs), "duplicate pairs in the neighbour list"
    assert all(a != b for a, b in pairs), "self pairs in the neighbour list"
    return set(pairs)


DOMAINS = {
    "2d-periodic": Domain(box=(1.0, 1.0), periodic=(True, True)),
    "2d-walled": Domain(box=(1.0, 0.7), periodic=(False, False)),
    "2d-channel": Domain(box=(1.0, 0.6), periodic=(True, False)),
    "3d-periodic": Domain(box=(1.0, 1.0, 1.0), periodic=(True, True, True)),
    "3d-walled": Domain(box=(1.0, 0.8, 0.9), periodic=(False, False, False)),
    "3d-mixed": Domain(box=(1.0, 0.6, 1.0), periodic=(True, False, True)),
}


def _positions(kind, domain, seed):
    box = np.asarray(domain.box)
    dx = 0.04 if domain.dim == 2 else 0.08
    if kind == "random":
        n = 600 if domain.dim == 2 else 800
        return np.random.default_rng(seed).uniform(0.0, 1.0, size=(n, domain.dim)) * box, dx
    r = cartesian([0.0] * domain.dim, box, dx)
    return np.mod(jitter(r, 0.05 * dx, seed), box), dx  # jittered lattice, wrapped into the box


@pytest.mark.parametrize("dtype", ["float64", "float32"])
@pytest.mark.parametrize("kind", ["random", "lattice"])
@pytest.mark.parametrize("name", list(DOMAINS))
def test_pair_sets_equal_jax_md(name, kind, dtype):
    domain = DOMAINS[name]
    r, dx = _positions(kind, domain, seed=len(name))
    cutoff, skin = 3.0 * dx, 0.5 * dx
    r = jnp.asarray(r, dtype)
    ours = make_neighbor_search(domain, cutoff, skin, backend="cell_sort").allocate(r)
    ref = make_neighbor_search(domain, cutoff, skin, backend="jax_md").allocate(r)
    assert not bool(ours.did_buffer_overflow) and not bool(ref.did_buffer_overflow)
    assert ours.idx.dtype == jnp.int32 and ours.idx.shape[0] == r.shape[0]
    mine, theirs = _pairs(ours.idx), _pairs(ref.idx)
    assert mine == theirs, f"missing {sorted(theirs - mine)[:5]}, extra {sorted(mine - theirs)[:5]}"
    assert len(mine) > 10 * r.shape[0], "meant to test a well-populated list"


def test_single_cell_dimensions_and_out_of_box_positions():
    """A periodic dimension too short for three cells (one cell, no double visits) and walled
    positions slightly outside [0, box) (wall layers) still give jax-md's pairs."""
    domain = Domain(box=(1.0, 0.25), periodic=(True, True))
    rng = np.random.default_rng(3)
    r = jnp.asarray(rng.uniform(0.0, 1.0, size=(300, 2)) * np.asarray(domain.box))
    for dom, pos in [(domain, r), (DOMAINS["2d-walled"], r * 0.7 - 0.02)]:
        ours = make_neighbor_search(dom, 0.1, 0.02, backend="cell_sort").allocate(pos)
        ref = make_neighbor_search(dom, 0.1, 0.02, backend="jax_md").allocate(pos)
        assert _pairs(ours.idx) == _pairs(ref.idx)


def _jitted_update(search):
    return jax.jit(search.update)


def test_overflow_when_crowded_into_one_cell():
    domain = DOMAINS["2d-periodic"]
    r, dx = _positions("lattice", domain, seed=1)
    search = make_neighbor_search(domain, 3 * dx, 0.5 * dx, backend="cell_sort")
    nbrs = search.allocate(jnp.asarray(r))
    update = _jitted_update(search)
    assert not bool(update(jnp.asarray(r), nbrs).did_buffer_overflow)
    # squeeze a quarter of the particles into a small patch: both capacities are exceeded
    crowded = r.copy()
    crowded[: len(r) // 4] = 0.5 + 0.01 * np.random.default_rng(2).uniform(size=(len(r) // 4, 2))
    out = update(jnp.asarray(crowded), nbrs)
    assert bool(out.did_buffer_overflow)
    # a re-allocation at the crowded state holds every pair again
    again = search.allocate(jnp.asarray(crowded))
    assert not bool(again.did_buffer_overflow)
    ref = make_neighbor_search(domain, 3 * dx, 0.5 * dx, backend="jax_md").allocate(jnp.asarray(crowded))
    assert _pairs(again.idx) == _pairs(ref.idx)


def test_overflow_of_neighbour_slots_or_cell_slots_alone():
    """Each capacity on its own: a build with ample cell slots but one neighbour slot too few, and
    one with ample neighbour slots but one cell slot too few, both raise the flag."""
    domain = DOMAINS["3d-periodic"]
    r, dx = _positions("random", domain, seed=4)
    search = make_neighbor_search(domain, 3 * dx, 0.5 * dx, 1.0, backend="cell_sort")
    nbrs = search.allocate(jnp.asarray(r))
    assert not bool(nbrs.did_buffer_overflow)
    k, c = nbrs.max_occupancy, nbrs.cell_list_capacity
    build = jax.jit(search.impl._build, static_argnums=(1, 2))
    assert not bool(build(jnp.asarray(r), c, k).did_buffer_overflow)
    short_k = build(jnp.asarray(r), c + 5, k - 1)
    assert bool(short_k.did_buffer_overflow)
    assert int(jnp.max(jnp.sum(short_k.idx < len(r), axis=1))) == k - 1  # filled up to K, no further
    assert bool(build(jnp.asarray(r), c - 1, k + 5).did_buffer_overflow)


@pytest.mark.parametrize("name", ["2d-channel", "3d-mixed"])
def test_verlet_skin_rebuilds_only_after_half_the_skin(name):
    domain = DOMAINS[name]
    r, dx = _positions("random", domain, seed=7)
    r = np.clip(r, 0.1, 0.9 * np.asarray(domain.box))  # keep walled moves inside the box
    cutoff, skin = 3.0 * dx, 0.5 * dx
    search = make_neighbor_search(domain, cutoff, skin, backend="cell_sort")
    update = _jitted_update(search)
    nbrs = search.allocate(jnp.asarray(r))
    rng = np.random.default_rng(8)
    step = rng.normal(size=r.shape)
    step *= 0.49 * skin / np.max(np.linalg.norm(step, axis=1))
    r1 = np.where(domain.periodic, np.mod(r + step, domain.box), r + step)
    nbrs1 = update(jnp.asarray(r1), nbrs)
    np.testing.assert_array_equal(np.asarray(nbrs1.idx), np.asarray(nbrs.idx))
    np.testing.assert_array_equal(np.asarray(nbrs1.reference_position), r)  # not rebuilt
    # every pair within the cutoff is still listed (the Verlet-skin guarantee)
    ref = make_neighbor_search(domain, cutoff, 0.0, backend="jax_md").allocate(jnp.asarray(r1))
    assert _pairs(ref.idx) <= _pairs(nbrs1.idx)
    # one particle moves 0.6 skin from the reference: rebuilt at r2, exact again
    r2 = r1.copy()
    r2[5] = r[5] + 0.6 * skin * np.eye(domain.dim)[0]
    r2 = np.where(domain.periodic, np.mod(r2, domain.box), r2)
    nbrs2 = update(jnp.asarray(r2), nbrs1)
    np.testing.assert_array_equal(np.asarray(nbrs2.reference_position), r2)
    ref2 = make_neighbor_search(domain, cutoff, skin, backend="jax_md").allocate(jnp.asarray(r2))
    assert _pairs(nbrs2.idx) == _pairs(ref2.idx)


# ---------------------------------------------------------------------------------------------------
# In the solver
# ---------------------------------------------------------------------------------------------------

DX = 0.05


def _tgv_solver(backend, effects=sph.Effects(tvf=True)):
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], DX), 0.1 * DX, seed=11, box=[1.0, 1.0])
    scene = tgv.scene(DX, sph.Material(eta=0.01), effects, r=r)
    return sph.build_solver(scene, sph.Numerics(dtype="float64", neighbor_search=backend))


def _close(a, b, rtol):
    for f in ("r", "u", "rho", "p", "dudt"):
        x, y = np.asarray(getattr(a, f)), np.asarray(getattr(b, f))
        d = x - y
        if f == "r":
            d = d - np.round(d)
        assert np.max(np.abs(d)) <= rtol * max(np.max(np.abs(y)), 1e-300), f"{f}: {np.max(np.abs(d)):.3g}"


@pytest.mark.parametrize("effects", [sph.Effects(tvf=True), sph.Effects(riemann=True, density_evolution=True)],
                         ids=["tvf", "riemann"])
def test_tgv_run_equals_jax_md(effects):
    n_steps = 60  # several rebuilds at dx 0.05 (skin / 2 is passed after ~20 steps)
    out = {}
    for backend in ("cell_sort", "jax_md"):
        solver = _tgv_solver(backend, effects)
        state, nbrs = solver.init_fn()
        chunk = jax.jit(rollout.make_chunk(solver.step_fn, n_steps))
        state, nbrs, reallocs = rollout.advance(chunk, solver.neighbors, state, nbrs, 0, n_steps)
        out[backend] = (state, nbrs)
    (a, na), (b, nb) = out["cell_sort"], out["jax_md"]
    assert _pairs(na.idx) == _pairs(nb.idx)  # same rebuilds at the same positions
    _close(a, b, 1e-11)


def test_gradient_through_scan_rollout_equals_jax_md():
    n_steps = 15
    grads = {}
    for backend in ("cell_sort", "jax_md"):
        solver = _tgv_solver(backend)
        template, _ = solver.init_fn()
        nbrs = solver.neighbors.allocate(template.r, extra_capacity=8)

        def loss(r):
            state0 = solver.state_at(jnp.mod(r, 1.0), template.u, nbrs)
            state, _, overflow = rollout.scan_rollout(solver.step_fn, state0, nbrs, n_steps)
            return kinetic_energy(state), overflow

        (value, overflow), g = jax.jit(jax.value_and_grad(loss, has_aux=True))(template.r)
        assert not bool(overflow)
        grads[backend] = (float(value), np.asarray(g))
    assert grads["cell_sort"][0] == pytest.approx(grads["jax_md"][0], rel=1e-12)
    ga, gb = grads["cell_sort"][1], grads["jax_md"][1]
    assert np.max(np.abs(ga - gb)) <= 1e-9 * np.max(np.abs(gb))
