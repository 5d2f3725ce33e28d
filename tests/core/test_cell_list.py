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
* Speed work: cell_sort is the default search; the bit-count compaction of a build equals the
  exclusive prefix sum; equal searches compare and hash equal (compiled allocation shared); the
  step evaluated in row blocks (sph.blocks) equals the unblocked step and its gradient
  to round-off for every kind of scene (walls, Riemann walls, re-initialization, heat, 3D), and
  operations across particles inside a blocked function are evaluated over all rows.
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
from sph_test_helpers import kinetic_energy, listed_pairs

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)


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


# float32 on the jittered lattice only: its pairs sit within the jitter (0.05 dx) of the cutoff 3 dx,
# where float32's rounding decides membership; random positions (crowded and empty cells) rarely do
@pytest.mark.parametrize("kind,dtype", [("random", "float64"), ("lattice", "float64"), ("lattice", "float32")])
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
    mine, theirs = listed_pairs(ours.idx), listed_pairs(ref.idx)
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
        assert listed_pairs(ours.idx) == listed_pairs(ref.idx)


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
    assert listed_pairs(again.idx) == listed_pairs(ref.idx)


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
    assert listed_pairs(ref.idx) <= listed_pairs(nbrs1.idx)
    # one particle moves 0.6 skin from the reference: rebuilt at r2, exact again
    r2 = r1.copy()
    r2[5] = r[5] + 0.6 * skin * np.eye(domain.dim)[0]
    r2 = np.where(domain.periodic, np.mod(r2, domain.box), r2)
    nbrs2 = update(jnp.asarray(r2), nbrs1)
    np.testing.assert_array_equal(np.asarray(nbrs2.reference_position), r2)
    ref2 = make_neighbor_search(domain, cutoff, skin, backend="jax_md").allocate(jnp.asarray(r2))
    assert listed_pairs(nbrs2.idx) == listed_pairs(ref2.idx)


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
    assert listed_pairs(na.idx) == listed_pairs(nb.idx)  # same rebuilds at the same positions
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


# ---------------------------------------------------------------------------------------------------
# Speed work (issue 11): the compaction of a build, the search as a static argument, row blocking
# ---------------------------------------------------------------------------------------------------

def test_default_search_is_cell_sort():
    assert sph.Numerics().neighbor_search == "cell_sort"
    assert make_neighbor_search(DOMAINS["2d-periodic"], 0.1, 0.02).backend == "cell_sort"


@pytest.mark.parametrize("c", [1, 7, 31, 32, 33, 80, 100])
def test_hits_before_is_the_exclusive_prefix_count(c):
    from sph.cell_list import _hits_before

    rng = np.random.default_rng(c)
    for density in (0.0, 0.1, 0.5, 1.0):
        hit = rng.uniform(size=(37, c)) < density
        expected = np.cumsum(hit, axis=1) - hit
        np.testing.assert_array_equal(np.asarray(jax.jit(_hits_before)(jnp.asarray(hit))), expected)


def test_equal_searches_share_their_compiled_allocation():
    from sph.cell_list import make_cell_list

    domain = DOMAINS["2d-periodic"]
    a, b = make_cell_list(domain, 0.12, 0.02), make_cell_list(domain, 0.12, 0.02)
    assert a == b and hash(a) == hash(b)
    assert a != make_cell_list(domain, 0.12, 0.03)


def _blocked_scenes():
    import dataclasses

    from sph.cases import tank, tgv3d

    mat, hot = sph.Material(eta=0.01), sph.Material(eta=0.01, kappa=0.1, c_p=1.0)

    def tank_scene(fx):
        return tank.scene(0.1, mat, fx, width=0.5, height=0.5, tank_length=1.0, tank_height=1.0)

    heated = tank_scene(sph.Effects(walls="no_slip", tvf=True))
    heated = dataclasses.replace(heated, material=hot, effects=dataclasses.replace(heated.effects, heat=True),
                                 T=1.0 + heated.r[:, 0], T_fixed=heated.wall_mask)
    # four scenes cover every pass the blocks run: periodic 3D with TVF; walls with Riemann SPH, the
    # evolved density and its re-initialization; free-slip walls with artificial viscosity; no-slip
    # walls with heat and TVF (a plain or TVF periodic 2D scene adds no pass to these)
    return {
        "tank_riemann_walls_reinit": tank_scene(sph.Effects(walls="no_slip", gravity=(0.0, -1.0), riemann=True,
                                                            density_evolution=True, density_reinit_every=2)),
        "tank_free_slip_av": tank_scene(sph.Effects(walls="free_slip", gravity=(0.0, -1.0), density_evolution=True,
                                                    artificial_viscosity=0.1)),
        "tank_heat_tvf": heated,
        "tgv3d_tvf": tgv3d.scene(tgv3d.dx_for(8), mat, sph.Effects(tvf=True)),
    }


BLOCKED_SCENES = _blocked_scenes()
GRADIENT_SCENES = ("tank_riemann_walls_reinit", "tank_heat_tvf")
"""The scenes whose gradient is also compared (blocked against unblocked): between them every pass
the blocks run in 2D with walls (Riemann walls, re-initialization, heat, TVF); the other two add
free-slip with artificial viscosity and 3D, whose forward step is compared."""


@pytest.mark.parametrize("name", list(BLOCKED_SCENES))
def test_row_blocked_step_and_gradient_equal_unblocked(name, monkeypatch):
    """The step evaluated in blocks of a few particles (sph.blocks, every pass, the last block
    overlapping the one before) gives the unblocked state to round-off, walls, Riemann
    walls, density re-initialization and heat included, and so does a gradient through two steps
    (GRADIENT_SCENES)."""
    import sph.blocks

    scene = BLOCKED_SCENES[name]

    def run(block_pairs):
        monkeypatch.setattr(sph.blocks, "BLOCK_PAIRS", block_pairs)
        solver = sph.build_solver(scene, sph.Numerics(dtype="float64"))
        state, nbrs = solver.init_fn()
        step = jax.jit(solver.step_fn)
        for k in range(1, 4):
            state, nbrs = step(state, nbrs, k)
        nbrs0 = solver.neighbors.allocate(jnp.asarray(scene.r))

        def loss(r0):
            s = solver.state_at(r0, jnp.asarray(scene.u), nbrs0)
            for k in range(1, 3):
                s, _ = solver.step_fn(s, nbrs0, k)
            return jnp.sum(s.u**2) + jnp.sum(s.rho)

        grad = jax.jit(jax.grad(loss))(jnp.asarray(scene.r)) if name in GRADIENT_SCENES else None
        scans = str(jax.make_jaxpr(solver.step_fn)(state, nbrs, 1)).count("scan[")
        return state, grad, scans

    ref, g_ref, scans_ref = run(1 << 40)                    # one block: the unblocked function
    k = int(sph.build_solver(scene).init_fn()[1].idx.shape[1])
    out, g, scans = run(k * 37)                                # blocks of 37 rows
    assert scans > scans_ref, "the blocked step should loop over blocks"
    for f in ("r", "u", "v", "rho", "p", "dudt", "dvdt", "T"):
        a, b = getattr(out, f), getattr(ref, f)
        if b is None:
            assert a is None
            continue
        scale = max(float(jnp.max(jnp.abs(b))), 1e-300)
        # p = c^2 (rho - rho_ref) cancels ~3 digits of rho's round-off
        assert float(jnp.max(jnp.abs(a - b))) <= (1e-11 if f != "p" else 1e-9) * scale, f
    if name in GRADIENT_SCENES:
        assert float(jnp.max(jnp.abs(g - g_ref))) <= 1e-10 * float(jnp.max(jnp.abs(g_ref)))


def test_blocks_join_every_row_once(monkeypatch):
    """`sph.blocks.over_rows` gives each row its own result exactly once, also when the last block
    overlaps the one before (50 rows in blocks of 7, 13 and 49 rows), and equals the whole list."""
    import sph.blocks

    n, k = 50, 6
    idx = jnp.asarray(np.random.default_rng(0).integers(0, n + 1, size=(n, k)), jnp.int32)
    x = jnp.asarray(np.random.default_rng(1).normal(size=n))

    def body(start, size, idx_rows):
        own = x if size is None else jax.lax.dynamic_slice_in_dim(x, start, size)
        rows = jnp.arange(n) if size is None else start + jnp.arange(size)
        return jnp.sum(jnp.where(idx_rows < n, x[jnp.minimum(idx_rows, n - 1)], 0.0), axis=1) * own, rows

    ref, ref_rows = body(0, None, idx)
    for rows in (7, 13, 49):
        monkeypatch.setattr(sph.blocks, "BLOCK_PAIRS", rows * k)
        out, got_rows = jax.jit(lambda idx: sph.blocks.over_rows(body, idx))(idx)
        np.testing.assert_array_equal(np.asarray(got_rows), np.arange(n))
        np.testing.assert_array_equal(np.asarray(out), np.asarray(ref))


def test_blocks_even_out(monkeypatch):
    """A row count just above the block target is split into equal blocks (50 rows at a target of 49:
    two blocks of 25, not 49 + 49 with 48 rows computed twice)."""
    import sph.blocks

    monkeypatch.setattr(sph.blocks, "BLOCK_PAIRS", 49 * 6)
    assert sph.blocks.block_rows(50, 6) == 25
    assert sph.blocks.block_rows(49, 6) == 49 and sph.blocks.block_rows(101, 6) == 34
