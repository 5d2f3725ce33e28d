"""`make sitl-cost PROFILE=smoke` (sitl/cost.py, run in .venv-lb through make) into a private results
folder: the accuracy-cost points of the fine solver and of the solver alone at temporal coarsening
M, checked against what the integrators guarantee, and their run records gathered by the atlas.

What the smoke data show, and why (sitl/README.md, "Accuracy against cost"): every model starts
from two stored frames, i.e. from the frame-averaged velocity d(r^0, r^-1) / Delta t, which lags the
instantaneous one by (Delta t / 2) a. L substeps of symplectic Euler from it miss the data (made by
symplectic Euler at dt, for which r^+1 - 2 r^0 + r^-1 = a Delta t^2 when a is constant over the
frames) by a Delta t^2 (1 - 1/L) / 2 per frame, so on a smooth flow whose coarse step stays stable
the solver's MSE_20 FALLS with M = W / L, as ((1 - 1/L) / (1 - 1/W))^2 above a floor; L = 1 (M = W)
is Stormer-Verlet on the frames and sits on that floor. The fine solver (the data's integrator at
its dt, started with the consistent velocity) is the floor, far below the same integrator started
with the lagging one (M = 1). Coarsening itself costs no accuracy here: the smoke flow is near
steady and c Delta t / h = 2 is still stable over 20 frames. The cost falls with M (fewer substeps).

Copies the tests' shared smoke dataset (sph_test_helpers.shared_sitl_dataset, made once per session; make
checks the copy against its recorded digests); never trains, so GNS / SitL are left out. FAILS, not skips,
when .venv-lb is missing."""
import csv
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from sph_test_helpers import require_lb_env, seed_sitl_dataset, sitl_env as _env

from experiments.accuracy import plot_accuracy as A
from sitl import settings as S
from lab import record
from lab.configtools import ConfigError
from lab.experiment import load_settings

ROOT = Path(__file__).resolve().parents[2]
SOLVER_M = (1, 2, 5, 10)        # the smoke profile's cost.coarsening; write_every W = 10
W = 10


def _make(results):
    return subprocess.run(["make", "sitl-cost", "PROFILE=smoke", f"RESULTS={results}"], cwd=ROOT, env=_env(),
                          capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def cost(tmp_path_factory):
    require_lb_env()
    results = tmp_path_factory.mktemp("results")
    seed_sitl_dataset(results)
    proc = _make(results)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with (S.out_dir(results) / "cost.csv").open() as f:
        rows = {r["name"]: r for r in csv.DictReader(f)}
    return results, rows, proc.stdout


def _mse(rows, name):
    return float(rows[name]["mse20"])


def test_points_outputs_and_no_training(cost):
    results, rows, out = cost
    assert set(rows) == {"fine", "solver_L3"} | {f"solver_M{m}" for m in SOLVER_M}
    for name, r in rows.items():
        assert r["finite"] == "True" and float(r["mse20"]) > 0 and float(r["ms_per_coarse_step"]) > 0, r
        assert int(r["n_rollouts"]) == 2 and (S.cost_dir(results) / name / "record.json").exists()
        if r["kind"] == "solver":
            assert int(r["substeps"]) * float(r["M"]) == pytest.approx(W)
    assert (S.out_dir(results) / "cost.png").stat().st_size > 10_000
    # cost.md, the table the READMEs show: one row per point, its MSE_20 and median time as in cost.csv
    md = [ln for ln in (S.out_dir(results) / "cost.md").read_text().splitlines() if ln.startswith("| ")][1:]
    assert len(md) == len(rows)
    for line, r in zip(md, rows.values()):
        cells = [c.strip() for c in line.strip("|").split("|")]
        assert cells[0] == r["method"] and cells[5].split()[0] == f"{float(r['mse20']):.3g}", (line, r)
        assert cells[7].split(" / ")[0] == f"{float(r['ms_per_coarse_step']):.3g}", (line, r)
    assert "GNS left out" in out and "SitL (L=3) left out" in out
    assert not (S.out_dir(results) / "ckp").exists()          # nothing was trained


def test_fine_solver_is_the_floor(cost):
    rows = cost[1]
    fine = _mse(rows, "fine")
    # the same integrator at the same dt and the same cost, started with the lagging velocity
    assert fine < _mse(rows, "solver_M1") / 100
    assert float(rows["fine"]["ms_per_coarse_step"]) == pytest.approx(float(rows["solver_M1"]["ms_per_coarse_step"]),
                                                                      rel=0.5)
    # M = W is Stormer-Verlet on the frames: consistent with the data too, on the same floor
    assert _mse(rows, "solver_M10") / 3 < fine < 3 * _mse(rows, "solver_M10")
    for name in rows:
        if name not in ("fine", "solver_M10"):
            assert fine < _mse(rows, name) / 30, name


def test_solver_error_follows_the_start_velocity_lag(cost):
    rows = cost[1]
    solver = sorted((float(r["M"]), float(r["mse20"])) for r in rows.values() if r["kind"] == "solver")
    mse = [e for _, e in solver]
    assert all(b < a for a, b in zip(mse, mse[1:])), solver         # falls with M, as derived above
    floor, top = _mse(rows, "solver_M10"), _mse(rows, "solver_M1")
    for m, e in solver:
        lag = (1 - m / W) / (1 - 1 / W)                            # (1 - 1/L) / (1 - 1/W), L = W / M
        assert (e - floor) / (top - floor) == pytest.approx(lag**2, rel=0.2), (m, e)


def test_cost_per_coarse_step_falls_with_M(cost):
    rows = cost[1]
    t = [float(rows[f"solver_M{m}"]["ms_per_coarse_step"]) for m in SOLVER_M]
    assert all(b < 1.05 * a for a, b in zip(t, t[1:])), t             # interleaved medians, 5 % for noise
    assert t[-1] < 0.8 * t[0], t                                      # 10 substeps -> 1 (plus a fixed part)


def test_records_are_gathered_by_the_atlas(cost):
    results, rows, _ = cost
    atlas = load_settings(ROOT / "experiments" / "accuracy", "smoke")
    assert "sitl" in atlas.gather
    runs = A.gather(atlas, results)
    sitl = runs[runs["experiment"] == "sitl"]
    assert len(sitl) == len(rows) and set(record.RECORD_COLUMNS) <= set(runs.columns)
    table = A.problem_table(runs, atlas, "Solver-in-the-Loop (RPF 2D)")
    assert len(table) == len(rows)
    for _, rec in sitl.iterrows():
        row = rows[Path(rec["folder"]).name]
        assert rec["err_mse20"] == pytest.approx(float(row["mse20"]))
        assert rec["ms_per_step"] == pytest.approx(float(row["ms_per_coarse_step"]))
        assert rec["wall_s"] == pytest.approx(20 * rec["ms_per_step"] / 1e3)
        assert rec["target"] == "sitl-cost" and np.isfinite(rec["err_mse5"])


def test_unchanged_inputs_are_not_measured_again(cost):
    results, _, _ = cost
    before = json.loads((S.out_dir(results) / "cost.json").read_text())["key"]
    proc = _make(results)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "sitl/{cost.csv, cost.png, cost.json, ...}: up to date with its runs" in proc.stdout, proc.stdout[-2000:]
    assert "cost: " not in proc.stdout                       # cost.py was not even started
    assert json.loads((S.out_dir(results) / "cost.json").read_text())["key"] == before


def test_damaged_cost_table_is_written_again_without_measuring(cost):
    """Issue 23, classes 1 and 3 for sitl-cost: a truncated cost.csv is noticed by make's check
    (lab.deliver) and written again from the measurements kept in cost.json, not re-timed."""
    results, rows, _ = cost
    csv_path = S.out_dir(results) / "cost.csv"
    before = json.loads((S.out_dir(results) / "cost.json").read_text())
    text = csv_path.read_text()
    csv_path.write_text(text[: len(text) // 2])
    proc = _make(results)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "cost.csv differs from what was made" in proc.stdout, proc.stdout[-2000:]
    assert f"{csv_path} changed since it was written (truncated?); written again from cost.json" in proc.stdout
    assert csv_path.read_text() == text
    assert json.loads((S.out_dir(results) / "cost.json").read_text())["rows"] == before["rows"]  # not re-measured


def test_atlas_reads_only_the_current_points(cost):
    """A record folder left from a point no longer configured is not gathered: cost.done (the stamp
    cost.py writes) lists exactly the current points, as the SPH experiments' stamps do."""
    results, rows, _ = cost
    cdir = S.cost_dir(results)
    stray = cdir / "solver_M7"
    shutil.copytree(cdir / "solver_M2", stray)
    try:
        runs = A.gather(load_settings(ROOT / "experiments" / "accuracy", "smoke"), results)
        folders = set(runs[runs["experiment"] == "sitl"]["folder"].map(lambda f: Path(f).name))
        assert folders == set(rows), folders
    finally:
        shutil.rmtree(stray)


def test_a_coarsening_that_does_not_divide_write_every_is_a_config_error():
    with pytest.raises(ConfigError, match=r"cost\.coarsening\[1\]: M = 3 does not divide data\.write_every = 10"):
        S.load("smoke", overrides={"cost": {"coarsening": [2, 3]}})


def test_the_planes_key_reads_its_points_not_the_whole_study(cost):
    """A study edit that adds no point to the plane (another SitL noise) leaves its key unchanged, so
    nothing is measured again; one that adds a point (a coarse SitL at another L) changes it."""
    results = cost[0]
    script = (
        "import json, sys\n"
        "from sitl import cost, settings as S\n"
        "path = S.data_dir(sys.argv[1])\n"
        "keys = {}\n"
        "for name, over in (('profile', {}), ('noise', {'study': {'noise': [0.0, 1.0e-5]}}),\n"
        "                   ('coarse', {'study': {'substeps': [1, 2]}})):\n"
        "    exp = S.load('smoke', overrides=over)\n"
        "    keys[name] = cost.inputs_key(exp, sys.argv[1], path, cost.points(exp), {})\n"
        "print(json.dumps(keys))\n")
    proc = subprocess.run([str(ROOT / ".venv-lb" / "bin" / "python"), "-c", script, str(results)], cwd=ROOT,
                          env=dict(_env(), PYTHONPATH=str(ROOT)), capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    keys = json.loads(proc.stdout.strip().splitlines()[-1])
    assert keys["noise"] == keys["profile"] and keys["coarse"] != keys["profile"], keys
