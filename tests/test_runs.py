"""sph.runs: cache keys that are exactly right, the cached run (skip / resume / repair), the run
record, metrics tables of exactly the current runs, make stamps, and a copied experiment folder
that works as a template."""
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

import sph
from sph import io, runs, stamp
from sph.cases import tgv

ROOT = Path(__file__).resolve().parents[1]
RUN_PY = ROOT / "experiments" / "ldc2d" / "run.py"


# -- cache keys -------------------------------------------------------------------------------------
@pytest.fixture
def sph_copy(tmp_path, monkeypatch):
    """A copy of sph/ that runs.code_fingerprint reads instead of the real one."""
    copy = tmp_path / "sph"
    shutil.copytree(ROOT / "sph", copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(runs, "SPH_ROOT", copy)
    return copy


def _edit_docstring(path: Path):
    s = path.read_text()
    i = s.index('"""') + 3
    path.write_text(s[:i] + "Edited docstring sentence. " + s[i:] + "\n# an added comment\n")


def test_docstring_and_io_edits_keep_the_cache_key(sph_copy):
    before = runs.code_fingerprint([RUN_PY])
    _edit_docstring(sph_copy / "io.py")
    (sph_copy / "io.py").write_text((sph_copy / "io.py").read_text() + "\nNEW_FORMAT_CONSTANT = 3\n")
    _edit_docstring(sph_copy / "momentum.py")
    runs._code_fingerprint.cache_clear()  # a new process would hash the edited files afresh
    assert runs.code_fingerprint([RUN_PY]) == before


def test_physics_edit_changes_the_cache_key(sph_copy):
    before = runs.code_fingerprint([RUN_PY])
    s = (sph_copy / "momentum.py").read_text()
    (sph_copy / "momentum.py").write_text(s + "\n\ndef _extra_term(x):\n    return 2 * x\n")
    assert runs.code_fingerprint([RUN_PY]) == before  # this process still runs the code it imported
    runs._code_fingerprint.cache_clear()  # a new process hashes the edited files afresh
    assert runs.code_fingerprint([RUN_PY]) != before


def test_closure_holds_the_physics_not_the_formats():
    mods = runs.sph_closure(runs.SOLVER_MODULES + ("sph.cases.ldc",))
    assert {"sph.momentum", "sph.riemann", "sph.walls", "sph.solver", "sph.cases.ldc"} <= set(mods)
    assert not set(mods) & runs.NUMBER_NEUTRAL


def test_import_sph_leaves_x64_off():
    out = subprocess.run([sys.executable, "-c", "import sph, jax; print(jax.config.jax_enable_x64)"],
                         capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


# -- the cached run -------------------------------------------------------------------------------
def _spec(folder, fp="a"):
    return runs.RunSpec(folder=folder, case="tgv2d", method="sph", fingerprint=fp, t_end=0.02, frames=4,
                        keep=("velocity",))


def _solver():
    return sph.build_solver(tgv.scene(0.1, sph.Material(), sph.Effects()), sph.Numerics())


def test_run_skip_repair_and_record(tmp_path, capsys):
    sp = _spec(tmp_path / "run")
    out = runs.run_cached(sp, _solver, progress=False)
    assert out.status == "run" and runs.stored_state(sp) == "current"
    n_frames = runs.read_metadata(sp.meta_path)["sequence_length"]
    assert (sp.folder / "traj.xdmf").read_text().count("<Grid Name=\"frame") == n_frames == 6  # 9 steps, every 2
    e_kin = io.read_trajectory(sp.traj)["e_kin"]
    assert runs.run_cached(sp, _solver, progress=False).status == "skipped"

    # a truncated trajectory is noticed, kept aside and redone to the same numbers
    data = sp.traj.read_bytes()
    sp.traj.write_bytes(data[: len(data) // 2])
    assert runs.stored_state(sp) == "damaged"
    assert runs.run_cached(sp, _solver, progress=False).status == "run"
    assert (sp.folder / "traj.h5.stale-0").exists()
    np.testing.assert_allclose(io.read_trajectory(sp.traj)["e_kin"], e_kin, rtol=1e-12)

    # other inputs: stale, set aside, run again
    sp2 = _spec(tmp_path / "run", fp="b")
    assert runs.stored_state(sp2) == "stale"
    runs.run_cached(sp2, _solver, progress=False)
    assert (sp.folder / "traj.h5.stale-1").exists()

    rec = runs.record(sp.folder, experiment="tgv2d", target="fig5", method="sph", errors={"e_kin": 0.1})
    assert list(rec)[:len(runs.RECORD_COLUMNS)] == list(runs.RECORD_COLUMNS)
    assert rec["n_particles"] == 100 and rec["dim"] == 2 and rec["err_e_kin"] == 0.1
    assert rec["n_steps"] == round(0.02 / _solver().dt) and rec["wall_s"] > 0 and rec["peak_rss_mb"] > 0


def test_damaged_metrics_table_names_its_file(tmp_path):
    bad = tmp_path / "metrics.csv"
    bad.write_bytes(b"")
    with pytest.raises(RuntimeError, match=r"metrics\.csv: damaged metrics table"):
        runs.read_table(bad)


def test_select_refuses_values_outside_the_config():
    assert runs.select("--dx", [0.05], [0.05, 0.04]) == [0.05]
    assert runs.select("--dx", None, [0.05]) is None
    with pytest.raises(sph.ConfigError, match=r"--dx 0\.03: not one of this profile's values"):
        runs.select("--dx", [0.03], [0.05, 0.04])


def test_stamp_changes_only_with_the_outputs(tmp_path):
    d = tmp_path / "out"
    d.mkdir()
    (d / "metadata.json").write_text("{}")
    st = d / "runs.done"
    assert stamp.update(st, d)
    assert not stamp.update(st, d)
    (d / "metrics.csv").write_text("a\n1\n")  # derived tables do not count
    assert not stamp.update(st, d)
    (d / "metadata.json").write_text('{"n_steps": 3}')
    assert stamp.update(st, d)


# -- a copied folder is an experiment of its own ------------------------------------------------------
def test_copied_experiment_folder_runs_unchanged(tmp_path):
    study = tmp_path / "my_study"
    shutil.copytree(ROOT / "experiments" / "tgv2d", study, ignore=shutil.ignore_patterns("__pycache__"))
    cfg = yaml.safe_load((study / "config.yaml").read_text())
    cfg["profiles"]["smoke"].update(dx=[0.1], t_end=0.05, frames=5, eval_times=[0.05],
                                    methods=[{"name": "tvf", "effects": {"tvf": True}}],
                                    relaxation={"steps": 20, "quench_every": 10})
    (study / "config.yaml").write_text(yaml.safe_dump(cfg))
    results = tmp_path / "results"
    env_cmd = [sys.executable, str(study / "run.py"), "--profile", "smoke", "--results", str(results), "--no-progress"]
    subprocess.run(env_cmd, check=True, cwd=tmp_path, capture_output=True, text=True)
    table = pd.read_csv(results / "my_study" / "metrics.csv")
    assert list(table["method"]) == ["tvf"] and table["n_particles"].tolist() == [100]
    assert (results / "my_study" / "tvf_dx0.1" / "record.json").exists()
    subprocess.run([sys.executable, str(study / "plot_fig5.py"), "--profile", "smoke", "--results", str(results),
                    "--out", str(results / "my_study" / "fig5")], check=True, cwd=tmp_path, capture_output=True)
    assert (results / "my_study" / "fig5" / "fig5.png").stat().st_size > 0
    # nothing was written into the repository's own tgv2d results
    assert not (results / "tgv2d").exists()
