"""End-to-end 2D Taylor-Green pipeline (experiments/tgv2d) on one coarse spacing and one method:
relaxation -> run -> traj.h5 (LagrangeBench layout) + metadata.json -> metrics.csv, then skipping
of finished runs, resuming of an interrupted run, and the driver's non-finite stop.

Tiny override of the smoke profile: TVF, dx = 0.05 (400 particles), t_end = 0.3, 100 relaxation
steps; a few seconds of stepping, the rest is compilation.
"""
import json
import shutil

import h5py
import jax.numpy as jnp
import numpy as np
import pandas as pd
import pytest

import sph
from sph import simulate
from lab import io, tables
from sph.cases import tgv
from lab.configtools import ConfigError
from lab.experiment import Experiment, load_settings
from sph_test_helpers import ROOT

TGV2D = ROOT / "experiments" / "tgv2d"
OVERRIDE = {"dx": [0.05], "methods": [{"name": "tvf", "effects": {"tvf": True}}], "t_end": 0.3, "frames": 6,
            "eval_times": [0.25, 1.0], "relaxation": {"steps": 100}}
DX = 0.05


def experiment(results, overrides=OVERRIDE) -> Experiment:
    return Experiment(TGV2D, "smoke", results, overrides=overrides)


def run_one(results, callback=None) -> dict:
    """Run (or skip, or resume) the one run of OVERRIDE into `results`; its metrics row, the table rebuilt."""
    exp = experiment(results)
    exp.run_one(exp.runs[0], progress=False, callback=callback)
    exp.write_table()
    return exp.metrics(exp.runs[0])


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """One uninterrupted run: (results folder, metrics row)."""
    results = tmp_path_factory.mktemp("tgv_full")
    return results, run_one(results)


def test_metrics_row_is_physical(finished):
    results, row = finished
    table = pd.read_csv(experiment(results).metrics_path)
    assert len(table) == 1
    got = table.iloc[0]
    assert (got["case"], got["method"], got["dx"], got["dtype"]) == ("tgv2d", "tvf", DX, "float64")
    assert got["n_particles"] == 400 and got["n_steps"] == round(0.3 / got["dt"])
    assert got["wall_s"] > 0 and got["compile_s"] > 0 and np.isfinite(got["ms_per_step"])
    for col in ("u_max_relerr_t0.25", "e_kin_relerr_t0.25", "u_max_relerr_mean", "e_kin_relerr_mean"):
        assert np.isfinite(got[col]), col
    # bounds derived from the measurement (2026-12-06, TVF, dx 0.05, relaxed 100 steps): E_kin 0.031,
    # u_max 0.119 from the analytical decay at t = 0.25. A viscous term 40 % too weak (patched into the
    # solver) gives 0.135 and 0.192: E_kin's bound (2x measured) catches it, u_max's (1.5x measured; the
    # maximum over 400 particles is dominated by the discretization at this dx) as well
    assert got["e_kin_relerr_t0.25"] < 0.063
    assert got["u_max_relerr_t0.25"] < 0.18
    assert got["density_error_max"] < 0.1  # weakly compressible, Ma = 0.1 (measured 0.063)
    assert np.isnan(got["u_max_relerr_t1"]) and np.isnan(got["e_kin_relerr_t1"])  # t > t_end


def test_trajectory_has_lagrangebench_layout(finished):
    results, _ = finished
    folder = results / "tgv2d" / "tvf_dx0.05"
    meta = json.loads((folder / "metadata.json").read_text())
    with h5py.File(folder / "traj.h5", "r") as f:
        assert list(f.keys()) == ["00000"]
        g = f["00000"]
        pos, ptype = g["position"], g["particle_type"]
        n_frames = pos.shape[0]
        assert pos.shape == (n_frames, 400, 2) and ptype.shape == (400,)
        assert np.all(ptype[...] == sph.FLUID)
        assert g["velocity"].shape == (n_frames, 400, 2)
        assert g["density"].shape == g["pressure"].shape == (n_frames, 400)
        assert g["time"].shape == (n_frames,) and g["time"][0] == 0.0
        assert np.all((pos[...] >= 0) & (pos[...] < 1))
        assert bool(g.attrs["complete"])
        assert {"r", "u", "v", "rho", "p", "mass", "tag", "dudt", "dvdt"} <= set(g["checkpoint"].keys())
        np.testing.assert_array_equal(g["checkpoint/r"][...], pos[-1])
    assert meta["sequence_length"] == n_frames
    n_steps = round(meta["t_end"] / meta["dt"])
    assert meta["write_every"] * (n_frames - 2) < n_steps <= meta["write_every"] * (n_frames - 1)
    for key in ("case", "solver", "dim", "dx", "dt", "t_end", "write_every", "num_particles_max",
                "periodic_boundary_conditions", "bounds", "default_connectivity_radius", "dtype",
                "vel_mean", "vel_std", "acc_mean", "acc_std"):
        assert key in meta, key
    assert meta["num_particles_max"] == 400 and meta["periodic_boundary_conditions"] == [True, True]
    assert meta["bounds"] == [[0.0, 1.0], [0.0, 1.0]]


def test_finished_run_is_skipped(finished):
    results, row = finished
    traj = results / "tgv2d" / "tvf_dx0.05" / "traj.h5"
    before = traj.stat().st_mtime_ns
    again = run_one(results)
    assert traj.stat().st_mtime_ns == before
    assert again["wall_s"] == row["wall_s"] and again["n_frames"] == row["n_frames"]
    assert len(pd.read_csv(experiment(results).metrics_path)) == 1  # rebuilt, not appended twice



def test_metrics_table_lists_exactly_the_current_runs(finished, tmp_path):
    """metrics.csv is rebuilt from the trajectories of the current config: a damaged table is
    replaced, and a switched dtype or a removed method leaves no row of the old config behind."""
    results, _ = finished
    work = tmp_path / "results"
    shutil.copytree(results, work)
    path = experiment(work).metrics_path
    path.write_bytes(path.read_bytes()[:40])  # truncated by a killed writer
    assert len(experiment(work).write_table()) == 1 and len(pd.read_csv(path)) == 1
    f32 = experiment(work, {**OVERRIDE, "numerics": {"dtype": "float32"}})
    assert f32.write_table().empty and not path.exists()  # no float32 run has finished
    other = experiment(work, {**OVERRIDE, "methods": [{"name": "sph", "effects": {}}], "fig4_method": "sph"})
    assert other.write_table().empty and not path.exists()
    with pytest.raises(FileNotFoundError, match="no metrics table"):
        tables.read_table(path)
    assert len(experiment(work).write_table()) == 1 and len(pd.read_csv(path)) == 1

class _Stop(Exception):
    pass


def test_interrupted_run_resumes_from_checkpoint(finished, tmp_path):
    results_full, row_full = finished
    # reuse the cached relaxation so that both runs start from the same particles
    for suffix in (".npy", ".json"):
        src = (results_full / "tgv2d" / "relaxed_dx0.05.npy").with_suffix(suffix)
        dst = (tmp_path / "tgv2d" / "relaxed_dx0.05.npy").with_suffix(suffix)
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(src, dst)

    half = row_full["n_steps"] // 2

    def stop_half_way(step, t, state):
        if step >= half:
            raise _Stop

    with pytest.raises(_Stop):
        run_one(tmp_path, callback=stop_half_way)
    traj = tmp_path / "tgv2d" / "tvf_dx0.05" / "traj.h5"
    status = io.trajectory_status(traj)
    assert status["exists"] and not status["complete"]
    assert half <= status["checkpoint_step"] < row_full["n_steps"]
    assert 1 < status["n_frames"] < row_full["n_frames"]

    row = run_one(tmp_path)
    assert row["n_frames"] == row_full["n_frames"] and row["n_steps"] == row_full["n_steps"]
    a = io.read_trajectory(traj)
    b = io.read_trajectory(results_full / "tgv2d" / "tvf_dx0.05" / "traj.h5")
    np.testing.assert_array_equal(a["step"], b["step"])
    # float64 and the same program: resumed equals uninterrupted to round-off (1e-12, as every resume check)
    np.testing.assert_allclose(a["e_kin"], b["e_kin"], rtol=1e-12)
    np.testing.assert_allclose(a["position"][-1], b["position"][-1], rtol=0, atol=1e-12)


def test_nonfinite_state_stops_with_particle_and_step():
    scene = tgv.scene(0.1, sph.Material(), sph.Effects())
    solver = sph.build_solver(scene, sph.Numerics())
    state, nbrs = solver.init_fn()
    state = state.replace(u=state.u.at[7, 1].set(jnp.nan))
    with pytest.raises(RuntimeError, match=r"step 0 .*particle 7 .*'u'"):
        simulate.run(solver, state, nbrs, t_end=10 * solver.dt, write_every=5, progress=False)


def test_blow_up_names_step_and_particle(tmp_path):
    """A time step 11x the CFL limit makes Riemann SPH blow up within a few steps: the driver stops,
    names the step and particle, and keeps the last good frame in the checkpoint."""
    scene = tgv.scene(0.1, sph.Material(), sph.Effects(riemann=True, density_evolution=True))
    solver = sph.build_solver(scene, sph.Numerics(dt=0.025))
    state, nbrs = solver.init_fn()
    with io.TrajectoryWriter.create(tmp_path / "t.h5", scene.tag, 2) as w:
        with pytest.raises(RuntimeError, match=r"blew up at step \d+ \(t=[0-9.]+\): particle \d+") as e:
            simulate.run(solver, state, nbrs, t_end=50 * solver.dt, write_every=5, writer=w, progress=False,
                         u_limit=10.0)
        bad_step = int(str(e.value).split("step ")[1].split()[0])
        _, ck_step, _ = w.load_checkpoint()
    assert ck_step < bad_step <= ck_step + 5
    assert io.trajectory_status(tmp_path / "t.h5")["n_frames"] == ck_step // 5 + 1


def test_bad_config_key_is_named():
    with pytest.raises(ConfigError, match=r"relaxation\.stpes: unknown key"):
        load_settings(TGV2D, "smoke", overrides={"relaxation": {"stpes": 3}})
    with pytest.raises(ConfigError, match=r"dx\[0\]"):
        load_settings(TGV2D, "smoke", overrides={"dx": [0.03]})
