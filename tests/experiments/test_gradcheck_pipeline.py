"""End-to-end gradient-check pipeline (gradcheck/, JAX-SPH Fig. 1) on the smoke profile in float64:
10 x 10 fluid lattice (dx = 0.1), Taylor-Green vortex and lid-driven cavity (walls inside the
gradient), 10 warm-up steps, d E_kin(5 more steps) / d r by jax.grad against central differences of
every fluid coordinate, the eps sweep, the gradient norm after 1 and 30 steps, both figures.

The smoke profile also runs float32; the test keeps float64 only (dtypes override) to stay within
its time budget. Independent reasons behind the bounds:
- central differences have truncation error O(eps^2) and, in float64, round-off ~1e-16 L / eps:
  at eps = 1e-3 dx both are far below 1e-4 relative, so AD must agree to better than 1e-4;
- the truncation error scales with eps^2, so a 10x larger step has a ~100x larger error;
- the periodic Taylor-Green vortex is invariant under a uniform translation of all particles (with
  their velocities), so the gradient summed over particles vanishes: sum_i dE/dr_i = 0.
"""
import numpy as np
import pandas as pd
import pytest

from lab.configtools import ConfigError
from gradcheck import plot as P
from gradcheck import run as R
from gradcheck import settings as S

OVERRIDES = {"dtypes": ["float64"], "fig1_dtypes": ["float64"]}


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    exp = S.load("smoke", overrides=OVERRIDES)
    results = tmp_path_factory.mktemp("gradcheck_smoke")
    table = R.check_all(exp, results)
    growth = R.growth_all(exp, results)
    P.plot_fig1(exp, results)
    P.plot_growth(exp, results)
    return exp, results, table, growth


def test_ad_matches_central_differences_in_float64(done):
    exp, results, table, _ = done
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
    _, results, _, _ = done
    with np.load(S.check_path(results, "tgv", "float64")) as z:
        g_ad, g_fd = z["g_ad"], z["g_fd"]
    scale = np.linalg.norm(g_ad)
    assert np.all(np.abs(g_ad.sum(axis=0)) < 1e-10 * scale)
    assert np.all(np.abs(g_fd.sum(axis=0)) < 1e-6 * scale)  # FD rounding, summed over 100 particles
    # the cavity is not invariant: its walls and lid fix the frame
    with np.load(S.check_path(results, "ldc", "float64")) as z:
        g = z["g_ad"]
    assert np.linalg.norm(g.sum(axis=0)) > 1e-3 * np.linalg.norm(g)


def test_eps_sweep_shows_second_order_truncation(done):
    exp, results, _, _ = done
    sweep = pd.read_csv(S.sweep_path(results))
    for case in ("tgv", "ldc"):
        sel = sweep[sweep["case"] == case].set_index("eps_factor")["rel_l2"]
        assert sel.index.size == len(exp.sweep_eps_factors)
        largest, paper = sel[max(exp.sweep_eps_factors)], sel[exp.eps_factor]
        assert paper < largest
        expected = (max(exp.sweep_eps_factors) / exp.eps_factor) ** 2  # (1e-2 / 1e-3)^2 = 100
        assert 0.3 * expected < largest / paper < 3 * expected
        assert paper < 1e-4


def test_gradient_norms_finite_for_every_length(done):
    exp, results, _, growth = done
    assert list(growth["n_steps"]) == list(exp.growth.steps) * 2 and max(growth["n_steps"]) <= 30
    assert np.all(np.isfinite(growth["grad_norm"])) and np.all(growth["grad_norm"] > 0)
    assert np.all(np.isfinite(growth["loss"]))
    # after 30 steps of the lid pulling the fluid, E_kin of the cavity has grown from rest-like values
    ldc = growth[growth["case"] == "ldc"].set_index("n_steps")["loss"]
    assert ldc[30] > ldc[1]


def test_outputs_exist_with_expected_columns(done):
    _, results, _, _ = done
    fig = S.fig_dir(results)
    for name in ("fig1.png", "fig1.pdf", "metrics.csv", "sweep.csv", "grad_norm_vs_steps.png",
                 "grad_norm_vs_steps.csv"):
        assert (fig / name).stat().st_size > 0, name
    table = pd.read_csv(fig / "metrics.csv")
    for col in ("case", "dtype", "rel_l2", "max_abs", "mse", "ad_s", "fd_s", "ad_compile_s", "fd_compile_s"):
        assert col in table.columns, col


def test_unchanged_check_is_skipped(done, capsys):
    exp, results, _, _ = done
    before = S.check_path(results, "tgv", "float64").stat().st_mtime_ns
    R.check_one(exp, exp.case("tgv"), "float64", results)
    assert "skipped" in capsys.readouterr().out
    assert S.check_path(results, "tgv", "float64").stat().st_mtime_ns == before


@pytest.mark.parametrize("override, key", [
    ({"loss_step": 5}, "loss_step"),
    ({"eps_factor": 3e-3}, "sweep_eps_factors"),
    ({"cases": [{"name": "ldc", "kind": "ldc"}]}, "cases[0].effects.walls"),
    ({"growth": {"steps": [30, 1]}}, "growth.steps"),
    ({"dtypes": ["float32"], "fig1_dtypes": []}, "dtypes"),
])
def test_config_errors_name_the_key(override, key):
    with pytest.raises(ConfigError, match=key.replace("[", r"\[").replace("]", r"\]")):
        S.load("smoke", overrides=override)
