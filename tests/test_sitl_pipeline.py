"""End to end: `make table1 fig3 PROFILE=smoke` (dataset generation with our solver, validation,
GNS and SitL training with LagrangeBench's Trainer, test-set inference with its metrics, Table 1
and Fig. 3), then an interrupted training continuing from its checkpoint. Runs .venv-lb through
make; FAILS, not skips, when .venv-lb is missing."""
import csv
import json
import math
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "smoke"


def _env():
    env = dict(os.environ, JAX_PLATFORMS="cpu", WANDB_MODE="disabled", PYTHONNOUSERSITE="1")
    env.pop("VIRTUAL_ENV", None)
    return env


def test_table1_and_fig3_smoke():
    if not (ROOT / ".venv-lb" / ".stamp").exists():
        pytest.fail(f"{ROOT / '.venv-lb'} is missing or incomplete: run `make setup-lb`", pytrace=False)
    proc = subprocess.run(["make", "table1", "fig3", "PROFILE=smoke"], cwd=ROOT, env=_env(), capture_output=True,
                          text=True, timeout=1800)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    with (RESULTS / "table1" / "table1.csv").open() as f:
        rows = {r["metric"]: r for r in csv.DictReader(f)}
    for metric in ("MSE_5", "MSE_20", "MSE_Ekin", "Sinkhorn"):
        for m in ("solver", "gns", "sitl"):
            v = float(rows[metric][f"{m}_ours"])
            assert math.isfinite(v) and v >= 0, (metric, m, v)
            assert float(rows[metric][f"{m}_paper"]) > 0
    assert "Solver only (paper)" in (RESULTS / "table1" / "table1.md").read_text()
    assert (RESULTS / "fig3" / "fig3.png").stat().st_size > 10_000
    meta = json.loads((RESULTS / "sitl" / "data" / "2D_RPF" / "metadata.json").read_text())
    gen = json.loads((RESULTS / "sitl" / "data" / "2D_RPF" / "generate.json").read_text())
    assert meta["dt"] == pytest.approx(gen["dt"]) and meta["write_every"] == 10
    assert gen["validation"]["profile_max_rel_error"] < 0.2
    for m in ("gns", "sitl"):
        assert json.loads((RESULTS / "sitl" / "ckp" / m / "train.json").read_text())["complete"]


def test_interrupted_training_resumes_from_its_checkpoint():
    side = RESULTS / "sitl" / "ckp" / "gns" / "train.json"
    if not side.exists():
        pytest.fail("run test_table1_and_fig3_smoke first (it trains the smoke GNS)", pytrace=False)
    record = json.loads(side.read_text())
    record["complete"] = False            # as if the run had been killed after its last checkpoint
    side.write_text(json.dumps(record))
    cmd = [str(ROOT / ".venv-lb" / "bin" / "python"), "sitl/train.py", "--profile", "smoke", "--results",
           str(RESULTS), "--model", "gns"]
    proc = subprocess.run(cmd, cwd=ROOT, env=dict(_env(), PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "resuming at step 20" in proc.stdout, proc.stdout[-2000:]
    again = subprocess.run(cmd, cwd=ROOT, env=dict(_env(), PYTHONPATH=str(ROOT)), capture_output=True, text=True,
                           timeout=900)
    assert again.returncode == 0 and "up to date" in again.stdout
