"""End-to-end stability suite (experiments/stability, a study of the protocol: lab.experiment) on the
smoke profile: every case runs through the harness, the table and its markdown copy have one row per
case, the known-stable cases pass, the known failures fail for the recorded reason, the deliberately
unstable control (dt 11x the CFL limit) is reported as failed with the driver's step/time/particle
message and its last good state stays on disk, a case that raises does not stop the others, and
cached results are reused (criteria re-evaluated without re-running). About 100 s of CPU time, most
of it compilation.
"""
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from experiments.stability import plot_stability as P
from lab import io
from lab.configtools import ConfigError
from lab.experiment import FAILURE, Experiment, load_settings

FOLDER = Path(P.__file__).resolve().parent
BLOWUP = re.compile(r"blew up at step (\d+) \(t=([0-9.e+-]+)\): particle (\d+)")


@pytest.fixture(scope="module")
def suite():
    return load_settings(FOLDER, "smoke")


def judged(exp, out) -> pd.DataFrame:
    out.mkdir(parents=True, exist_ok=True)
    return P.write_table(exp, out).set_index("case", drop=False)


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """The whole smoke suite, run once: (results folder, experiment, table indexed by case)."""
    results = tmp_path_factory.mktemp("stability")
    exp = Experiment(FOLDER, "smoke", results)
    exp.run_all(progress=False)
    return results, exp, judged(exp, results / "stability")


def test_table_has_one_row_per_case(suite, done):
    results, exp, _ = done
    out = results / "stability"
    csv = pd.read_csv(out / "stability.csv")
    assert list(csv["case"]) == suite.names() == [r.name for r in exp.runs]
    assert set(P.COLUMNS) <= set(csv.columns)
    assert csv["criterion"].str.startswith("finite").all()
    md = (out / "stability.md").read_text()
    for name in suite.names():
        assert f"| {name} |" in md
        assert (out / name / "traj.h5").exists() and (out / name / "metadata.json").exists()
    assert "## Criteria" in md and "## Messages" in md
    assert len(pd.read_csv(out / "metrics.csv")) == len(suite.names())  # the harness's table: every case


def test_known_stable_cases_pass(suite, done):
    _, _, table = done
    stable = [c.name for c in suite._cases if c.expected == "pass"]
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
    table = done[2]
    for name in ("dambreak_riemann", "dambreak_sph"):  # dissipated, never created
        row = table.loc[name]
        assert row["energy_end"] < 0 and row["energy_drift"] <= 0.01
    for name in ("heat_sine", "heat_step"):  # conserved to round-off, thermal limit binds
        row = table.loc[name]
        assert row["energy_drift"] < 1e-12 and row["dt_binding"] == "thermal" and row["T_overshoot"] < 1e-12
        assert abs(row["accuracy"]) < 0.01  # first mode decays as exp(-alpha k^2 t)


def test_every_case_behaves_as_expected(done):
    table = done[2]
    assert table["as_expected"].all(), table.loc[~table["as_expected"], ["case", "failed_checks"]]


def test_lattice_tgv_fails_on_energy_not_finiteness(done):
    """From the unrelaxed lattice the vortex collapses (tensile instability) but stays finite."""
    table = done[2]
    for name in ("tgv_lattice_sph", "tgv_lattice_tvf", "tgv_lattice_riemann"):
        row = table.loc[name]
        assert row["status"] == "completed" and not row["passed"]
        assert "ekin_relerr" in row["failed_checks"] and row["energy_drift"] > 0.5


def test_heat_beyond_its_limit_is_caught_by_the_overshoot_check(done):
    row = done[2].loc["heat_dt_beyond_limit"]
    assert not row["passed"] and "overshoot" in row["failed_checks"] and row["T_overshoot"] > 1.0


def test_blow_up_is_reported_with_step_time_particle_and_last_state_on_disk(done):
    results, exp, table = done
    row = table.loc["control_huge_dt"]
    assert row["status"] == "blew_up" and not row["passed"] and row["failed_checks"].startswith("blew_up")
    m = BLOWUP.search(row["message"])
    assert m, row["message"]
    bad_step, t_bad = int(m[1]), float(m[2])
    assert t_bad == pytest.approx(bad_step * row["dt"], rel=1e-5)
    folder = results / "stability" / "control_huge_dt"
    traj = folder / "traj.h5"
    assert str(traj) in row["message"]
    state, ck_step, _ = io.load_checkpoint(traj)
    assert ck_step < bad_step <= ck_step + row["write_every"]
    for name in state.field_names():
        a = np.asarray(getattr(state, name))
        assert np.all(np.isfinite(a)), name
    assert row["checkpoint_finite"] and row["checkpoint_step"] == ck_step
    assert row["t_reached"] == pytest.approx(ck_step * row["dt"])
    assert not io.trajectory_status(traj)["complete"]
    failure = io.read_metadata(folder / FAILURE)  # the outcome the harness recorded under the run's key
    assert "RuntimeError" in failure["kinds"] and failure["fingerprint"] == exp.spec(exp.run("control_huge_dt")).fingerprint
    assert exp.state(exp.run("control_huge_dt")) == "current"


def test_rerun_reuses_results_and_reevaluates_criteria(done, tmp_path):
    results, _, _ = done
    out = results / "stability"
    stamps = {p: p.stat().st_mtime_ns for p in [*out.glob("*/traj.h5"), *out.glob(f"*/{FAILURE}")]}
    strict = Experiment(FOLDER, "smoke", results,
                        overrides={"cases": {"heat_sine": {"criteria": {"density_error_max": 1e-9}}}})
    assert {strict.run_one(r, progress=False).status for r in strict.runs} == {"skipped"}  # nothing re-ran
    strict.write_table()
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps
    table = judged(strict, tmp_path / "judged")
    assert not table.loc["heat_sine", "passed"] and table.loc["heat_sine", "failed_checks"] == "density_error"
    assert table.loc["heat_step", "passed"]


def test_a_case_that_raises_does_not_stop_the_suite(tmp_path, monkeypatch):
    exp = Experiment(FOLDER, "smoke", tmp_path)
    real = exp.study.scene

    def broken(case, r=None):
        if case.kind == "heat" and case.temperature == "sine":
            raise ValueError("broken on purpose")
        return real(case, r)

    monkeypatch.setattr(exp.study, "scene", broken)
    exp.run_all(only=["heat_sine", "heat_step"], progress=False)
    rows = {r.name: P.evaluate(r, exp.metrics(r), exp.study.EKIN_WINDOW) for r in exp.runs
            if r.name in ("heat_sine", "heat_step")}
    assert rows["heat_sine"]["status"] == "error" and not rows["heat_sine"]["passed"]
    assert "ValueError: broken on purpose" in rows["heat_sine"]["message"]
    assert rows["heat_step"]["passed"]
    assert list(pd.read_csv(exp.metrics_path)["case"]) == ["heat_sine", "heat_step"]
    failure = tmp_path / "stability" / "heat_sine" / FAILURE
    assert "broken on purpose" in failure.read_text()
    assert exp.run_one(exp.run("heat_sine"), progress=False).status == "skipped"  # a recorded failure is current


def test_key_follows_simulation_settings_only(tmp_path):
    def key(**case):
        exp = Experiment(FOLDER, "smoke", tmp_path, overrides={"cases": {"heat_sine": case}} if case else None)
        return exp.spec(exp.run("heat_sine")).fingerprint

    fp = key()
    assert key(criteria={"density_error_max": 0.0}, expected="fail", note="judged") == fp
    assert key(t_end=0.06) != fp


def test_bad_config_key_is_named():
    with pytest.raises(ConfigError, match=r"cases\.heat_sine\.t_edn: unknown key"):
        load_settings(FOLDER, "smoke", {"cases": {"heat_sine": {"t_edn": 1.0}}})
    with pytest.raises(ConfigError, match=r"cases\.ldc_tvf\.effects\.walls"):
        load_settings(FOLDER, "smoke", {"cases": {"ldc_tvf": {"effects": {"walls": None}}}})
