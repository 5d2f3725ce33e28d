"""The droplet experiment through make, from a copy of its folder (the protocol's template promise):
`make <copy>` runs it cached, its table holds the Laplace error, its figure is made, and a second
make re-runs nothing. The physics bound is test_surface_tension's; here the pipeline."""
import subprocess

import pandas as pd

from sph_test_helpers import ROOT, copied_experiment


def make(results, folder, *targets):
    return subprocess.run(["make", *targets, "PROFILE=smoke", f"RESULTS={results}", f"PROTOCOL_DIRS={folder}"],
                          cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_a_copied_droplet_folder_is_an_experiment_of_its_own(tmp_path):
    folder = copied_experiment("droplet", tmp_path / "my_drop", n_side=[20], t_end=2.5, average_from=2.0)
    results = tmp_path / "results"
    out = make(results, folder, "my_drop")
    assert out.returncode == 0, out.stderr[-2000:]
    df = pd.read_csv(results / "my_drop" / "metrics.csv")
    assert list(df["run"]) == ["n20"] and list(df["experiment"]) == ["my_drop"]
    # Laplace at R / dx = 5 over t in [2, 2.5]: measured 4-5 %, the law within 10 %
    assert df["err_laplace"].iloc[0] < 0.10
    assert (results / "my_drop" / "laplace.png").stat().st_size > 10_000
    assert (results / "my_drop" / "n20" / "record.json").exists()
    again = make(results, folder, "my_drop")
    assert again.returncode == 0, again.stderr[-2000:]
    assert "n20: complete, skipped" in again.stdout and "up to date" in again.stdout


def test_a_plot_run_by_hand_names_the_missing_run(tmp_path):
    folder = copied_experiment("droplet", tmp_path / "other_drop", n_side=[20])
    out = subprocess.run([str(ROOT / ".venv/bin/python"), str(folder / "plot_laplace.py"), "--profile", "smoke",
                          "--results", str(tmp_path / "none")], capture_output=True, text=True, timeout=300)
    assert out.returncode == 4
    assert "runs n20 are missing" in out.stderr and "make other_drop PROFILE=smoke" in out.stderr
