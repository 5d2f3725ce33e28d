"""A cache is keyed by what it computed (issue 38): the cavity's plot script run by hand after a
config change used to cache a metrics row under the new config's key computed from the old
trajectory (t_end 4, 3520 steps, u_rms 0.0401 kept by every later make, true 0.0544). Now it refuses
in one line naming the stale run, caches nothing, and the next run gives the new numbers."""
import json
import subprocess
import sys

import pandas as pd

from sph_test_helpers import copied_experiment


def test_a_hand_run_plot_after_a_config_change_names_the_stale_run_and_poisons_nothing(tmp_path):
    small = dict(figures={"fig6": 0.05}, t_end=0.05, frames=2, analysis={"average_frames": 2, "steady_window": 0.02},
                 methods=[{"name": "tvf", "effects": {"tvf": True}}])
    ldc = copied_experiment("ldc2d", tmp_path / "ldc2d", **small)
    results = tmp_path / "results"

    def script(name, *extra):
        return subprocess.run([sys.executable, str(ldc / name), "--profile", "smoke", "--results", str(results),
                               "--fig", "fig6", *extra], capture_output=True, text=True, timeout=600)

    assert script("run.py", "--no-progress").returncode == 0
    row_file = results / "ldc2d" / "tvf_dx0.05" / "metrics_row.json"
    first = json.loads(row_file.read_text())
    assert abs(first["row"]["t_end"] - 0.05) < 1e-9
    copied_experiment_cfg = ldc / "config.yaml"
    copied_experiment_cfg.write_text(copied_experiment_cfg.read_text().replace("t_end: 0.05", "t_end: 0.1"))
    out = script("plot.py")
    assert out.returncode == 4, out.stdout + out.stderr
    assert "run tvf_dx0.05 was made from other inputs" in out.stderr
    assert json.loads(row_file.read_text()) == first          # nothing cached under the new key
    assert script("run.py", "--no-progress").returncode == 0
    assert abs(json.loads(row_file.read_text())["row"]["t_end"] - 0.1) < 1e-9
    table = pd.read_csv(results / "ldc2d" / "metrics.csv")
    assert list(table["t_end"].round(9)) == [0.1]
