"""A cache is keyed by what it computed (issue 38): the cavity's plot script run by hand after a
config change used to cache a metrics row under the new config's key computed from the old
trajectory (t_end 4, 3520 steps, u_rms 0.0401 kept by every later make, true 0.0544). Now the plot
refuses in one line naming the stale run (lab.experiment: a figure reads only current runs), writes
nothing, and the next run gives the new numbers."""
import subprocess
import sys

import pandas as pd

from sph_test_helpers import copied_experiment


def test_a_hand_run_plot_after_a_config_change_names_the_stale_run_and_poisons_nothing(tmp_path):
    small = dict(figures={"fig6": 0.05}, t_end=0.05, frames=2, analysis={"average_frames": 2, "steady_window": 0.02},
                 methods=[{"name": "tvf", "effects": {"tvf": True}}])
    ldc = copied_experiment("ldc2d", tmp_path / "ldc2d", **small)
    results = tmp_path / "results"
    common = ["--profile", "smoke", "--results", str(results)]

    def runs():
        return subprocess.run([sys.executable, "-m", "lab.experiment", str(ldc), *common, "--group", "fig6",
                               "--no-progress"], capture_output=True, text=True, timeout=600)

    def plot():
        return subprocess.run([sys.executable, str(ldc / "plot_fig6.py"), *common, "--out", str(tmp_path / "fig6")],
                              capture_output=True, text=True, timeout=600)

    assert runs().returncode == 0
    table = results / "ldc2d" / "metrics.csv"
    first = table.read_bytes()
    assert abs(pd.read_csv(table)["t_end"].iloc[0] - 0.05) < 1e-9
    cfg = ldc / "config.yaml"
    cfg.write_text(cfg.read_text().replace("t_end: 0.05", "t_end: 0.1"))
    out = plot()
    assert out.returncode == 4, out.stdout + out.stderr
    assert "run tvf_dx0.05 of profile smoke is stale" in out.stderr and "make ldc2d PROFILE=smoke" in out.stderr
    assert table.read_bytes() == first and not (tmp_path / "fig6" / "fig6.png").exists()  # nothing written
    assert runs().returncode == 0
    assert list(pd.read_csv(table)["t_end"].round(9)) == [0.1]
