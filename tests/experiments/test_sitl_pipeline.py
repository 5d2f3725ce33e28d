"""End to end: `make table1 fig3 PROFILE=smoke` (dataset generation with our solver, validation,
GNS and SitL training with LagrangeBench's Trainer, test-set inference with its metrics, Table 1
and Fig. 3), checked beyond finiteness (solver only against a bound from the data alone, the
spread of every number, the paper's training settings), then an interrupted training continuing
from its checkpoint, and damaged files repaired by the next make. Into a results folder of this
module's own (the dataset copied from the tests' shared smoke dataset). Runs .venv-lb through make;
FAILS, not skips, when .venv-lb is missing."""
import csv
import json
import math
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from sph_test_helpers import require_lb_env, seed_sitl_dataset, sitl_env as _env

from sitl import settings as S

ROOT = Path(__file__).resolve().parents[2]


def _frozen_mse5(path: Path, n_windows: int) -> float:
    """MSE_5 of particles frozen at the last input frame, over the first test windows (22 frames:
    2 inputs, 20 targets; one seed): the mean over k = 1..5 of the mean squared periodic
    displacement between frame 1 and frame 1 + k of each window."""
    box = np.array([1.0, 2.0])
    with h5py.File(path / "test.h5", "r") as f:
        pos = f["00000/position"][:].astype(np.float64)
    out = []
    for w in range(n_windows):
        ref = pos[22 * w + 1]
        for k in range(1, 6):
            d = pos[22 * w + 1 + k] - ref
            d -= box * np.round(d / box)
            out.append(np.mean(np.sum(d**2, axis=-1)))
    return float(np.mean(out))


@pytest.fixture(scope="module")
def smoke_made(tmp_path_factory):
    """`make table1 fig3 PROFILE=smoke` into a results folder of this module, once (the models are
    trained once; the later tests damage its files and make again). The dataset is the tests' shared
    one, copied: make checks the copy against its recorded digests."""
    require_lb_env()
    results = tmp_path_factory.mktemp("smoke")
    seed_sitl_dataset(results)
    proc = subprocess.run(["make", "table1", "fig3", "PROFILE=smoke", f"RESULTS={results}"], cwd=ROOT, env=_env(),
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return results


def test_table1_and_fig3_smoke(smoke_made):
    RESULTS = smoke_made
    with (RESULTS / "table1" / "table1.csv").open() as f:
        rows = {r["metric"]: r for r in csv.DictReader(f)}
    for metric in ("MSE_5", "MSE_20", "MSE_Ekin", "Sinkhorn"):
        for m in ("solver", "gns", "sitl"):
            v = float(rows[metric][f"{m}_ours"])
            assert math.isfinite(v) and v >= 0, (metric, m, v)
            assert float(rows[metric][f"{m}_paper"]) > 0
    assert "Solver only (paper)" in (RESULTS / "table1" / "table1.md").read_text()
    # the solver alone is never trained: no training noise, steps or wall time in its column
    for metric in ("training noise_std", "training steps", "training wall s"):
        assert rows[metric]["solver_ours"] == "" and rows[metric]["sitl_ours"] != "", (metric, rows[metric])
    # every number with its spread: per-window values, a bootstrap interval around the mean
    for m in ("solver", "gns", "sitl"):
        met = json.loads((RESULTS / "sitl" / "metrics" / f"{m}.json").read_text())
        assert met["n_rollouts"] == 2 and len(met["per_window"]["mse20"]) == 2 and met["window_seeds"] == [0, 0]
        lo, hi = met["ci_mse20"]
        assert lo <= met["mse20"] <= hi, (m, met["ci_mse20"])
        assert float(rows["MSE_20"][f"{m}_lo"]) == pytest.approx(lo)
    # solver only tracks the flow: its MSE_5 far below what particles frozen at the last input frame
    # would score, computed from the test data alone (the frame-to-frame displacements)
    frozen = _frozen_mse5(RESULTS / "sitl" / "data" / "2D_RPF", n_windows=2)
    solver = json.loads((RESULTS / "sitl" / "metrics" / "solver.json").read_text())
    assert frozen > 1e-5, frozen                              # the flow moves
    assert solver["mse5"] < 1e-3 * frozen, (solver["mse5"], frozen)
    # the paper's settings were the ones trained
    for m, noise in (("gns", 1e-3), ("sitl", 1e-5)):
        tr = json.loads((RESULTS / "sitl" / "ckp" / m / "train.json").read_text())
        assert tr["noise_std"] == noise and tr["lr_start"] == 1e-3, (m, tr)
    assert (RESULTS / "fig3" / "fig3.png").stat().st_size > 10_000
    # Fig. 3 over a long horizon (smoke: 50 coarse steps, the paper's 500): every model rolled out that
    # far on every test window that long; the solver alone stays finite and its error grows
    recs = {m: json.loads((RESULTS / "fig3" / "rollouts" / m / "record.json").read_text()) for m in ("solver", "gns", "sitl")}
    for m, rec in recs.items():
        assert rec["steps"] >= 50 and rec["n_windows"] >= 1 and all(len(w) == rec["steps"] for w in rec["mse_steps"]), m
    solver_mse = recs["solver"]["mse_steps"]
    assert all(math.isfinite(x) for w in solver_mse for x in w)
    assert all(w[-1] > w[0] for w in solver_mse), [(w[0], w[-1]) for w in solver_mse]
    with (RESULTS / "fig3" / "mse_steps.csv").open() as f:
        table = list(csv.DictReader(f))
    at50 = {r["model"]: r for r in table if r["step"] == "50"}
    assert set(at50) == {"solver", "gns", "sitl"}
    assert float(at50["solver"]["mean"]) == pytest.approx(sum(w[49] for w in solver_mse) / len(solver_mse), rel=1e-9)
    # a diverged window is counted, not averaged: the mean is over the finite ones (none: an empty cell)
    for m, r in at50.items():
        n_bad = sum(not math.isfinite(w[49]) for w in recs[m]["mse_steps"])
        assert int(r["diverged"]) == n_bad and (r["mean"] == "") == (n_bad == int(r["n_windows"])), (m, r)
    assert (RESULTS / "fig3" / "fig3_mse.png").stat().st_size > 10_000
    meta = json.loads((RESULTS / "sitl" / "data" / "2D_RPF" / "metadata.json").read_text())
    gen = json.loads((RESULTS / "sitl" / "data" / "2D_RPF" / "generate.json").read_text())
    assert meta["dt"] == pytest.approx(gen["dt"]) and meta["write_every"] == 10
    assert gen["validation"]["profile_max_rel_error"] < 0.2
    for m in ("gns", "sitl"):
        assert json.loads((RESULTS / "sitl" / "ckp" / m / "train.json").read_text())["complete"]


def test_interrupted_training_resumes_from_its_checkpoint(smoke_made):
    RESULTS = smoke_made
    side = RESULTS / "sitl" / "ckp" / "gns" / "train.json"
    record = json.loads(side.read_text())
    record["complete"] = False            # as if the run had been killed after its last checkpoint
    side.write_text(json.dumps(record))
    cmd = [str(ROOT / ".venv-lb" / "bin" / "python"), "sitl/train.py", "--profile", "smoke", "--results",
           str(RESULTS), "--model", "gns"]
    proc = subprocess.run(cmd, cwd=ROOT, env=dict(_env(), PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "resuming at step 10" in proc.stdout, proc.stdout[-2000:]
    again = subprocess.run(cmd, cwd=ROOT, env=dict(_env(), PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                           timeout=900)
    assert again.returncode == 0 and "up to date" in again.stdout


# -- issue 23, class 3: damaged SitL files are named, set aside and made again by the next make -----
# On the smoke results made above (this module's own folder).
@pytest.fixture(scope="module")
def made(smoke_made):
    return smoke_made


def _make_table1(results):
    """`make table1 PROFILE=smoke` as the fixture ran it (the same results folder: the same
    commands, so the deliverables' records match and only what is damaged is made again)."""
    proc = subprocess.run(["make", "table1", "PROFILE=smoke", f"RESULTS={results}"], cwd=ROOT, env=_env(),
                          capture_output=True, text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc.stdout


def _truncate(p: Path) -> bytes:
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    return data


@pytest.fixture(scope="module")
def damaged_and_made_again(made):
    """One make repairs five damaged files at once (each would cost a make of its own: the dataset's
    regeneration re-checks every model): a truncated GNS checkpoint, a validation split deleted by
    hand, a truncated test split, a metrics file cut mid-write and a cut Table 1. The tests below
    check what it did to each. Every damaged dataset file is set aside before the regeneration
    overwrites it, the split is regenerated without a traceback, and the damaged checkpoint is
    trained again from scratch on the regenerated (identical) data."""
    ckp = made / "sitl" / "ckp" / "gns"
    damaged = ckp / "best" / "params_tree.pkl"
    cut = len(_truncate(damaged)) // 2
    data = made / "sitl" / "data" / "2D_RPF"
    original = {"valid": (data / "valid.h5").read_bytes(), "test": _truncate(data / "test.h5")}
    (data / "valid.h5").unlink()
    metrics = made / "sitl" / "metrics" / "solver.json"
    good = json.loads(metrics.read_text())
    metrics.write_text('{"mse5": 1.0, ')                      # cut mid-write
    table = made / "table1" / "table1.md"
    table.write_text(table.read_text()[:100])
    out = _make_table1(made)
    return {"out": out, "ckp": ckp, "damaged": damaged, "cut": cut, "data": data, "original": original,
            "metrics": metrics, "good": good, "table": table}


def test_truncated_checkpoint_is_set_aside_and_trained_again(made, damaged_and_made_again):
    d = damaged_and_made_again
    ckp, damaged, cut, out = d["ckp"], d["damaged"], d["cut"], d["out"]
    assert f"{damaged} is damaged" in out and "training gns again" in out, out[-3000:]
    assert "train gns: from scratch" in out
    aside = max(ckp.parent.glob("gns.stale-*"), key=lambda p: p.stat().st_mtime)
    assert (aside / "best" / "params_tree.pkl").stat().st_size == cut  # kept as it was
    assert (aside / "train.json").exists()
    assert json.loads((ckp / "train.json").read_text())["complete"]
    with (made / "table1" / "table1.csv").open() as f:
        assert math.isfinite(float({r["metric"]: r for r in csv.DictReader(f)}["MSE_20"]["gns_ours"]))
    assert "train sitl: up to date" in out and "evaluate sitl: up to date" in out  # same data: kept


def test_a_deleted_split_is_regenerated_in_one_line(made, damaged_and_made_again):
    """A split deleted by hand used to make the next make try to set the missing file aside and crash
    with a FileNotFoundError traceback, on every later make too."""
    d = damaged_and_made_again
    data, original, out = d["data"], d["original"], d["out"]
    assert f"{data / 'valid.h5'}: missing" in out and "generating the dataset again" in out, out[-3000:]
    assert "Traceback" not in out
    assert (data / "valid.h5").read_bytes() == original["valid"]  # regenerated: the same data (deterministic)


def test_every_damaged_split_is_set_aside_before_the_regeneration(made, damaged_and_made_again):
    """The truncated test split is named and kept although another split (valid.h5) was found first:
    the regeneration overwrites every split, so each damaged one is set aside (it used to be only the
    first)."""
    d = damaged_and_made_again
    data, original, out = d["data"], d["original"], d["out"]
    assert f"{data / 'test.h5'}: damaged" in out, out[-3000:]
    aside = max(data.glob("test.h5.stale-*"), key=lambda p: p.stat().st_mtime)
    assert len(aside.read_bytes()) == len(original["test"]) // 2    # the damaged file is kept as it was
    assert (data / "test.h5").read_bytes() == original["test"]        # regenerated: the same data
    with h5py.File(data / "test.h5", "r") as f:
        assert f["00000/position"].shape[0] == S.load("smoke").data.frames[2]   # the whole test split


def test_damaged_metrics_and_table_are_made_again(made, damaged_and_made_again):
    d = damaged_and_made_again
    metrics, out = d["metrics"], d["out"]
    assert f"{metrics}: damaged (not readable as JSON" in out and "evaluating solver again" in out, out[-3000:]
    assert json.loads(metrics.read_text())["mse20"] == pytest.approx(d["good"]["mse20"], rel=1e-6)
    assert "Solver only (paper)" in d["table"].read_text()
    assert "is damaged" not in _make_table1(made)            # repaired: the next make trusts it


def test_a_second_training_of_one_model_waits_for_the_first(tmp_path):
    """Two trainings of one model at once used to write into one folder: now the second waits for the
    first's lock (held here by the test) and writes nothing meanwhile."""
    import signal
    import time

    from lab.lock import folder_lock

    sys_py = ROOT / ".venv-lb" / "bin" / "python"
    ckp_parent = tmp_path / "sitl" / "ckp"
    with folder_lock(ckp_parent, name=".gns.train.lock"):
        proc = subprocess.Popen([str(sys_py), str(ROOT / "sitl" / "train.py"), "--profile", "smoke", "--results",
                                 str(tmp_path), "--model", "gns"], cwd=ROOT, env=_env(), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        lines, t0 = [], time.time()
        while time.time() - t0 < 120:
            line = proc.stdout.readline()
            lines.append(line)
            if "waiting for it" in line or proc.poll() is not None:
                break
        assert any("being written by pid" in x and "waiting for it" in x for x in lines), "".join(lines)
        assert proc.poll() is None and not (ckp_parent / "gns").exists()
        proc.send_signal(signal.SIGKILL)
        proc.wait()
