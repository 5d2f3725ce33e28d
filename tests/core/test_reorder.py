"""Particle reordering by cell (sph.reorder, numerics.reorder_every in sph.simulate.run).

- the cell permutation puts a shuffled lattice back in lattice (x-major) order and leaves walls and
  temperature-fixed particles in their slots;
- a run that reorders every few steps gives the run that never does, to round-off, in the scene's
  order: frames, written positions, final state (periodic TGV with TVF, and the walled cavity whose
  fluid particles start shuffled);
- a resumed run reorders before its first chunk (its checkpoint is in the scene's order);
- a run that fails after reordering names the same step and particle (scene numbering) and hands
  back the same last good state as the run that never reorders.
"""
import dataclasses

import h5py
import numpy as np
import pytest

import sph
from sph import reorder, simulate
from lab import io
from sph.cases import ldc, tgv
from sph.errors import BlowUp
from sph.domain import Domain
from sph.lattice import cartesian, jitter
from sph.scene import Scene
from sph.state import FLUID, WALL

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

MAT = sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0)


def _shuffled(scene, seed=0):
    """The scene with its fluid particles in a random order among the fluid slots."""
    slots = np.flatnonzero(scene.tag == FLUID)
    perm = np.arange(scene.n)
    perm[slots] = np.random.default_rng(seed).permutation(slots)
    kw = {f.name: getattr(scene, f.name)[perm] for f in dataclasses.fields(scene)
          if isinstance(getattr(scene, f.name), np.ndarray) and getattr(scene, f.name).shape[:1] == (scene.n,)}
    return dataclasses.replace(scene, **kw)


def test_cell_permutation_restores_lattice_order_and_keeps_walls():
    dx = 0.1
    lattice = cartesian([0.0, 0.0], [1.0, 1.0], dx)          # x-major: x, then y
    walls = np.array([[-0.05, 0.5], [1.05, 0.5], [0.5, -0.05]])
    rng = np.random.default_rng(3)
    shuffle = rng.permutation(len(lattice))
    r = np.concatenate([walls[:1], lattice[shuffle], walls[1:]])
    movable = np.r_[False, np.ones(len(lattice), bool), False, False]
    perm = reorder.cell_permutation(r, movable, dx)
    assert perm[0] == 0 and list(perm[-2:]) == [len(r) - 2, len(r) - 1]
    np.testing.assert_array_equal(r[perm][1:-2], lattice)
    assert sorted(perm) == list(range(len(r)))


def test_movable_mask_excludes_walls_and_fixed_temperatures():
    tag = np.array([FLUID, FLUID, WALL, FLUID])
    scene = type("S", (), {"tag": tag, "T_fixed": np.array([False, True, True, False]),
                           "normal": np.array([[0, 0], [0, 0], [0, 1.0], [0, 0]])})()
    np.testing.assert_array_equal(reorder.movable_mask(scene), [True, False, False, True])


def _run(scene, numerics, steps, write_every, reorder_every, path=None, **kw):
    solver = sph.build_solver(scene, numerics)
    state, nbrs = solver.init_fn()
    if path is None:
        return simulate.run(solver, state, nbrs, t_end=0.0, n_steps=steps, write_every=write_every,
                            progress=False, reorder_every=reorder_every, **kw)
    with io.TrajectoryWriter.create(path, scene.tag, scene.dim, keep=("velocity",)) as w:
        return simulate.run(solver, state, nbrs, t_end=0.0, n_steps=steps, write_every=write_every, writer=w,
                            progress=False, reorder_every=reorder_every, **kw)


@pytest.mark.parametrize("case", ["tgv_tvf", "cavity"])
def test_reordered_run_equals_unreordered(case, tmp_path):
    if case == "tgv_tvf":
        r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], 0.05), 0.1 * 0.05, seed=1, box=(1.0, 1.0))
        scene = _shuffled(tgv.scene(0.05, MAT, sph.Effects(tvf=True), r=r))
    else:
        scene = _shuffled(ldc.scene(0.05, MAT, sph.Effects(walls="no_slip")))
    numerics = sph.Numerics(dtype="float64")
    plain = _run(scene, numerics, 60, 5, 0, tmp_path / "plain.h5")
    sorted_ = _run(scene, numerics, 60, 5, 10, tmp_path / "sorted.h5")
    assert plain.n_reorders == 0 and sorted_.n_reorders == 5
    for f in ("r", "u", "rho", "p"):
        a, b = getattr(sorted_.state, f), getattr(plain.state, f)
        assert float(np.max(np.abs(np.asarray(a) - np.asarray(b)))) <= 1e-10 * float(np.max(np.abs(b))), f
    np.testing.assert_allclose(sorted_.e_kin, plain.e_kin, rtol=1e-11)
    with h5py.File(tmp_path / "plain.h5") as fa, h5py.File(tmp_path / "sorted.h5") as fb:
        np.testing.assert_allclose(fb["00000/position"][...], fa["00000/position"][...], atol=1e-10)
        np.testing.assert_allclose(fb["00000/velocity"][...], fa["00000/velocity"][...], atol=1e-9)
    # the returned list belongs to the returned (scene-order) state: the next step equals a fresh list's
    solver = sph.build_solver(scene, numerics)
    a, _ = solver.step_fn(sorted_.state, sorted_.nbrs, 61)
    b, _ = solver.step_fn(sorted_.state, solver.neighbors.allocate(sorted_.state.r), 61)
    np.testing.assert_allclose(np.asarray(a.u), np.asarray(b.u), atol=1e-12)


def test_resumed_run_reorders_at_once(tmp_path):
    """A run resumed from its checkpoint (stored in the scene's order) sorts the particles before its
    first chunk, not `reorder_every` steps later, and still ends where the uninterrupted run ends."""
    scene = _shuffled(ldc.scene(0.05, MAT, sph.Effects(walls="no_slip")))
    numerics = sph.Numerics(dtype="float64")
    plain = _run(scene, numerics, 40, 5, 0)
    _run(scene, numerics, 20, 5, 10, tmp_path / "part.h5")
    solver = sph.build_solver(scene, numerics)
    with io.TrajectoryWriter.open(tmp_path / "part.h5") as w:
        state, nbrs, step = simulate.resume(solver, w)
        assert step == 20
        resumed = simulate.run(solver, state, nbrs, t_end=0.0, n_steps=40, write_every=5, writer=w,
                               progress=False, step0=step, reorder_every=10)
    assert resumed.n_reorders == 2  # before the chunks at steps 20 and 30 (only at 30 before the fix)
    np.testing.assert_allclose(np.asarray(resumed.state.r), np.asarray(plain.state.r), atol=1e-10)
    np.testing.assert_allclose(resumed.e_kin, plain.e_kin, rtol=1e-11)


def test_failure_after_reordering_names_the_scene_particle():
    """Particles at rest on a jittered periodic lattice under a uniform body force speed up together;
    the speed limit stops the run. With reordering every 5 steps the diagnosis names the same step and
    particle, and carries the same last good state (scene order), as without."""
    dx = 0.1
    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), 0.02 * dx, seed=2, box=(1.0, 1.0))
    scene = _shuffled(Scene(name="push", dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)), material=MAT,
                            effects=sph.Effects(gravity=(50.0, 0.0)), r=r, u=np.zeros_like(r),
                            tag=np.full(len(r), FLUID, np.int32)), seed=4)
    numerics = sph.Numerics(dtype="float64")
    dt = sph.build_solver(scene, numerics).dt
    limit = 50.0 * dt * 33.5          # crossed at step ~34, after six reorders
    errors = {}
    for every in (0, 5):
        with pytest.raises(BlowUp) as e:
            _run(scene, numerics, 60, 5, every, u_limit=limit)
        errors[every] = e.value
    assert 30 <= errors[0].step <= 40
    assert (errors[5].step, errors[5].particle) == (errors[0].step, errors[0].particle)
    np.testing.assert_allclose(np.asarray(errors[5].state.r), np.asarray(errors[0].state.r), atol=1e-12)
    assert f"particle {errors[0].particle} " in str(errors[5])


def test_reorder_every_is_validated():
    with pytest.raises(ValueError, match="numerics.reorder_every"):
        sph.Numerics(reorder_every=-1)
    with pytest.raises(ValueError, match="numerics.reorder_every"):
        sph.Numerics(reorder_every=2.5)
