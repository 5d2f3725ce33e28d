"""End-to-end gradient-check pipeline (gradcheck/, JAX-SPH Fig. 1) on the smoke profile in float64:
10 x 10 fluid lattice (dx = 0.1), Taylor-Green vortex and lid-driven cavity (walls inside the
gradient), 10 warm-up steps, d E_kin(5 more steps) / d r by jax.grad against central differences of
every fluid coordinate, the eps sweep, the gradient norm after 1 and 30 steps, both figures; the runs are
the study's (gradcheck/study.py), computed and cached by the harness (lab.experiment `compute`).

The smoke profile also runs float32; the test keeps float64 only (dtypes override) to stay within
its time budget. Independent reasons behind the bounds:
- central differences have truncation error O(eps^2) and, in float64, round-off ~1e-16 L / eps:
  at eps = 1e-3 dx both are far below 1e-4 relative, so AD must agree to better than 1e-4;
- the truncation error scales with eps^2, so a 10x larger step has a ~100x larger error;
- the periodic Taylor-Green vortex is invariant under a uniform translation of all particles (with
  their velocities), so the gradient summed over particles vanishes: sum_i dE/dr_i = 0.
"""
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from gradcheck import plot_fig1 as P1
from gradcheck import plot_grad_norm_vs_steps as P2
from lab.configtools import ConfigError
from lab.experiment import Experiment, load_settings

FOLDER = Path(P1.__file__).resolve().parent
OVERRIDES = {"dtypes": ["float64"], "fig1_dtypes": ["float64"]}


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """(settings, results, metrics.csv, grad_growth.csv, the harness's Experiment); the figures in <results>/fig1."""
    results = tmp_path_factory.mktemp("gradcheck_smoke")
    ex = Experiment(FOLDER, "smoke", results, overrides=OVERRIDES)
    ex.run_all(progress=False)
    fig = results / "fig1"
    fig.mkdir()
    P1.plot(ex, fig)
    P2.plot(ex, fig)
    table = pd.read_csv(ex.metrics_path)
    growth = pd.read_csv(ex.out_dir / "grad_growth.csv")
    return ex.settings, results, table, growth, ex


def check(results, case, dtype):
    with np.load(Path(results) / "gradcheck" / f"{case}_{dtype}" / "check.npz") as z:
        return {k: z[k] for k in z.files}


def test_ad_matches_central_differences_in_float64(done):
    exp, results, table, _, _ = done
    assert exp.dx == 0.1 and exp.eps == pytest.approx(1e-4)
    assert list(table["case"]) == ["tgv", "ldc"] and set(table["dtype"]) == {"float64"}
    for _, row in table.iterrows():
        assert row["n_fluid"] == 100 and row["n_fd_evals"] == 4 * row["n_fluid"]
        assert row["nonfinite_ad"] == 0
        assert row["grad_norm_ad"] > 0 and row["loss"] > 0
        assert row["rel_l2"] < 1e-4, row["case"]
        assert row["max_abs"] < 1e-4 * row["grad_norm_ad"]
        assert 0 < row["mse"] <= row["max_abs"] ** 2
        assert row["ad_s"] > 0 and row["fd_s"] > 0
    assert table.loc[table["case"] == "ldc", "n_particles"].item() == 16 * 16  # 3 wall layers around 10 x 10


def test_taylor_green_gradient_is_translation_invariant(done):
    _, results, _, _, _ = done
    z = check(results, "tgv", "float64")
    g_ad, g_fd = z["g_ad"], z["g_fd"]
    scale = np.linalg.norm(g_ad)
    assert np.all(np.abs(g_ad.sum(axis=0)) < 1e-10 * scale)
    assert np.all(np.abs(g_fd.sum(axis=0)) < 1e-6 * scale)  # FD rounding, summed over 100 particles
    # the cavity is not invariant: its walls and lid fix the frame
    g = check(results, "ldc", "float64")["g_ad"]
    assert np.linalg.norm(g.sum(axis=0)) > 1e-3 * np.linalg.norm(g)


def test_eps_sweep_shows_second_order_truncation(done):
    exp, results, _, _, _ = done
    sweep = pd.read_csv(results / "fig1" / "sweep.csv")
    for case in ("tgv", "ldc"):
        sel = sweep[sweep["case"] == case].set_index("eps_factor")["rel_l2"]
        assert sel.index.size == len(exp.sweep_eps_factors)
        largest, paper = sel[max(exp.sweep_eps_factors)], sel[exp.eps_factor]
        assert paper < largest
        expected = (max(exp.sweep_eps_factors) / exp.eps_factor) ** 2  # (1e-2 / 1e-3)^2 = 100
        assert 0.3 * expected < largest / paper < 3 * expected
        assert paper < 1e-4


def test_gradient_norms_finite_for_every_length(done):
    exp, results, _, growth, _ = done
    assert list(growth["n_steps"]) == list(exp.growth.steps) * 2 and max(growth["n_steps"]) <= 30
    assert np.all(np.isfinite(growth["grad_norm"])) and np.all(growth["grad_norm"] > 0)
    assert np.all(np.isfinite(growth["loss"]))
    # after 30 steps of the lid pulling the fluid, E_kin of the cavity has grown from rest-like values
    ldc = growth[growth["case"] == "ldc"].set_index("n_steps")["loss"]
    assert ldc[30] > ldc[1]


def test_outputs_exist_with_expected_columns(done):
    _, results, _, _, _ = done
    fig = results / "fig1"
    for name in ("fig1.png", "fig1.pdf", "metrics.csv", "sweep.csv", "grad_norm_vs_steps.png",
                 "grad_norm_vs_steps.csv"):
        assert (fig / name).stat().st_size > 0, name
    table = pd.read_csv(fig / "metrics.csv")
    for col in ("case", "dtype", "rel_l2", "max_abs", "mse", "ad_s", "fd_s", "ad_compile_s", "fd_compile_s"):
        assert col in table.columns, col


def test_unchanged_check_is_skipped(done, capsys):
    _, results, _, _, ex = done
    path = results / "gradcheck" / "tgv_float64" / "check.npz"
    before = path.stat().st_mtime_ns
    assert ex.run_one(ex.run("tgv_float64"), progress=False).status == "skipped"
    assert "skipped" in capsys.readouterr().out
    assert path.stat().st_mtime_ns == before
    # a run whose inputs changed is not current: the figures refuse it until it is computed again
    other = Experiment(FOLDER, "smoke", results, overrides={**OVERRIDES, "warmup_steps": 9})
    assert other.state(other.run("tgv_float64")) == "stale"
    assert other.state(other.run("growth_tgv_n1")) == "current"  # the warm-up is no input of a growth run


@pytest.mark.parametrize("override, key", [
    ({"loss_step": 5}, "loss_step"),
    ({"eps_factor": 3e-3}, "sweep_eps_factors"),
    ({"cases": [{"name": "ldc", "kind": "ldc"}]}, "cases[0].effects.walls"),
    ({"growth": {"steps": [30, 1]}}, "growth.steps"),
    ({"dtypes": ["float32"], "fig1_dtypes": []}, "dtypes"),
])
def test_config_errors_name_the_key(override, key):
    with pytest.raises(ConfigError, match=key.replace("[", r"\[").replace("]", r"\]")):
        load_settings(FOLDER, "smoke", overrides=override)
