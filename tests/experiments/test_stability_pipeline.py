"""End-to-end stability suite (experiments/stability) on the smoke profile: every case runs, the table
and its markdown copy have one row per case, the known-stable cases pass, the known failures fail
for the recorded reason, the deliberately unstable control (dt 11x the CFL limit) is reported as
failed with the driver's step/time/particle message and its last good state stays on disk, a case
that raises does not stop the others, and cached results are reused (criteria re-evaluated without
re-running). About 100 s of CPU time, most of it compilation.
"""
import dataclasses
import re

import numpy as np
import pandas as pd
import pytest

from lab import io
from lab.configtools import ConfigError
from experiments.stability import cases as C
from experiments.stability import run as R
from experiments.stability import settings as S

BLOWUP = re.compile(r"blew up at step (\d+) \(t=([0-9.e+-]+)\): particle (\d+)")


@pytest.fixture(scope="module")
def suite():
    return S.load("smoke")


@pytest.fixture(scope="module")
def done(suite, tmp_path_factory):
    """The whole smoke suite, run once: (results folder, table indexed by case)."""
    results = tmp_path_factory.mktemp("stability")
    table = R.run_suite(suite, results, progress=False)
    return results, table.set_index("case", drop=False)


def test_table_has_one_row_per_case(suite, done):
    results, _ = done
    csv = pd.read_csv(S.table_path(results))
    assert list(csv["case"]) == suite.names()
    assert set(R.COLUMNS) <= set(csv.columns)
    assert csv["criterion"].str.startswith("finite").all()
    md = S.markdown_path(results).read_text()
    for name in suite.names():
        assert f"| {name} |" in md
        assert (S.case_dir(results, name) / "result.json").exists()
    assert "## Criteria" in md and "## Messages" in md


def test_known_stable_cases_pass(suite, done):
    _, table = done
    stable = [name for name, case in suite.cases if case.expected == "pass"]
    assert {"dambreak_riemann", "dambreak_sph", "ldc_tvf", "ldc_sph", "tgv_long_tvf", "heat_sine",
            "heat_step"} <= set(stable)
    for name in stable:
        row = table.loc[name]
        assert row["passed"], f"{name}: {row['failed_checks']} {row['message']}"
        assert row["status"] == "completed" and row["finite_throughout"] and row["checkpoint_finite"]
        assert row["t_reached"] == pytest.approx(row["n_steps"] * row["dt"])
        assert abs(row["t_reached"] - suite.case(name).t_end) <= 0.5 * row["dt"] * (1 + 1e-9)
        assert row["n_crossed_wall"] == 0 and row["n_left_domain"] == 0
        assert row["density_error_max"] <= 0.05 and np.isfinite(row["wall_s"]) and row["ms_per_step"] > 0


def test_energy_checks_are_physical(done):
    _, table = done
    for name in ("dambreak_riemann", "dambreak_sph"):  # dissipated, never created
        row = table.loc[name]
        assert row["energy_end"] < 0 and row["energy_drift"] <= 0.01
    for name in ("heat_sine", "heat_step"):  # conserved to round-off, thermal limit binds
        row = table.loc[name]
        assert row["energy_drift"] < 1e-12 and row["dt_binding"] == "thermal" and row["T_overshoot"] < 1e-12
        assert abs(row["accuracy"]) < 0.01  # first mode decays as exp(-alpha k^2 t)


def test_every_case_behaves_as_expected(done):
    _, table = done
    assert table["as_expected"].all(), table.loc[~table["as_expected"], ["case", "failed_checks"]]


def test_lattice_tgv_fails_on_energy_not_finiteness(done):
    """From the unrelaxed lattice the vortex collapses (tensile instability) but stays finite."""
    _, table = done
    for name in ("tgv_lattice_sph", "tgv_lattice_tvf", "tgv_lattice_riemann"):
        row = table.loc[name]
        assert row["status"] == "completed" and not row["passed"]
        assert "ekin_relerr" in row["failed_checks"] and row["energy_drift"] > 0.5


def test_heat_beyond_its_limit_is_caught_by_the_overshoot_check(done):
    row = done[1].loc["heat_dt_beyond_limit"]
    assert not row["passed"] and "overshoot" in row["failed_checks"] and row["T_overshoot"] > 1.0


def test_blow_up_is_reported_with_step_time_particle_and_last_state_on_disk(suite, done):
    results, table = done
    row = table.loc["control_huge_dt"]
    assert row["status"] == "blew_up" and not row["passed"] and row["failed_checks"].startswith("blew_up")
    m = BLOWUP.search(row["message"])
    assert m, row["message"]
    bad_step, t_bad = int(m[1]), float(m[2])
    assert t_bad == pytest.approx(bad_step * row["dt"], rel=1e-5)
    traj = S.case_dir(results, "control_huge_dt") / "traj.h5"
    assert str(traj) in row["message"]
    state, ck_step, _ = io.load_checkpoint(traj)
    assert ck_step < bad_step <= ck_step + row["write_every"]
    for name in state.field_names():
        a = np.asarray(getattr(state, name))
        assert np.all(np.isfinite(a)), name
    assert row["checkpoint_finite"] and row["checkpoint_step"] == ck_step
    assert row["t_reached"] == pytest.approx(ck_step * row["dt"])
    assert not io.trajectory_status(traj)["complete"]


def test_rerun_reuses_results_and_reevaluates_criteria(done):
    results, _ = done
    stamps = {p: p.stat().st_mtime_ns for p in S.out_dir(results).glob("*/result.json")}
    strict = S.load("smoke", overrides={"cases": {"heat_sine": {"criteria": {"density_error_max": 1e-9}}}})
    table = R.run_suite(strict, results, progress=False).set_index("case")
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # nothing re-ran
    assert not table.loc["heat_sine", "passed"] and table.loc["heat_sine", "failed_checks"] == "density_error"
    assert table.loc["heat_step", "passed"]


def test_a_case_that_raises_does_not_stop_the_suite(suite, tmp_path, monkeypatch):
    real = C.build_scene

    def broken(case, progress=True):
        if case.kind == "heat" and case.temperature == "sine":
            raise ValueError("broken on purpose")
        return real(case, progress)

    monkeypatch.setattr(C, "build_scene", broken)
    table = R.run_suite(suite, tmp_path, only=["heat_sine", "heat_step"], progress=False).set_index("case")
    assert list(table.index) == ["heat_sine", "heat_step"]
    assert table.loc["heat_sine", "status"] == "error" and not table.loc["heat_sine", "passed"]
    assert "ValueError: broken on purpose" in table.loc["heat_sine", "message"]
    assert table.loc["heat_step", "passed"]


def test_fingerprint_follows_simulation_settings_only(suite):
    case = suite.case("heat_sine")
    fp = S.case_fingerprint("heat_sine", case)
    judged = dataclasses.replace(case, criteria=S.Criteria(density_error_max=0.0), expected="fail")
    assert S.case_fingerprint("heat_sine", judged) == fp
    assert S.case_fingerprint("heat_sine", dataclasses.replace(case, t_end=0.06)) != fp


def test_bad_config_key_is_named():
    with pytest.raises(ConfigError, match=r"cases\.heat_sine\.t_edn: unknown key"):
        S.load("smoke", overrides={"cases": {"heat_sine": {"t_edn": 1.0}}})
    with pytest.raises(ConfigError, match=r"cases\.ldc_tvf\.effects\.walls"):
        S.load("smoke", overrides={"cases": {"ldc_tvf": {"effects": {"walls": None}}}})
