"""The harness (lab): cache keys that are exactly right (keys), the cached run (skip / resume /
repair: runs), the run record (record), metrics tables of exactly the current runs (tables), make
stamps, a copied experiment folder that works as a template, and arrows only from harness to core."""
import ast
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import sph
from lab import cli, io, keys, record, runs, stamp, tables
from sph.cases import tgv
from sph_test_helpers import copied_experiment

ROOT = Path(__file__).resolve().parents[2]
RUN_PY = ROOT / "experiments" / "ldc2d" / "study.py"


# -- cache keys -------------------------------------------------------------------------------------
@pytest.fixture
def sph_copy(tmp_path, monkeypatch):
    """A copy of sph/ and lab/ that keys.code_fingerprint reads instead of the real ones."""
    for pkg in keys.PACKAGES:
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(keys, "ROOT", tmp_path)
    return tmp_path / "sph"


def _edit_docstring(path: Path):
    s = path.read_text()
    i = s.index('"""') + 3
    path.write_text(s[:i] + "Edited docstring sentence. " + s[i:] + "\n# an added comment\n")


def test_docstring_and_io_edits_keep_the_cache_key(sph_copy):
    before = keys.code_fingerprint([RUN_PY])
    io_py = sph_copy.parent / "lab" / "io.py"
    _edit_docstring(io_py)
    io_py.write_text(io_py.read_text() + "\nNEW_FORMAT_CONSTANT = 3\n")
    _edit_docstring(sph_copy / "momentum.py")
    keys._code_fingerprint.cache_clear()  # a new process would hash the edited files afresh
    assert keys.code_fingerprint([RUN_PY]) == before


def test_physics_edit_changes_the_cache_key(sph_copy):
    before = keys.code_fingerprint([RUN_PY])
    s = (sph_copy / "momentum.py").read_text()
    (sph_copy / "momentum.py").write_text(s + "\n\ndef _extra_term(x):\n    return 2 * x\n")
    assert keys.code_fingerprint([RUN_PY]) == before  # this process still runs the code it imported
    keys._code_fingerprint.cache_clear()  # a new process hashes the edited files afresh
    assert keys.code_fingerprint([RUN_PY]) != before


def test_closure_holds_the_physics_not_the_formats():
    mods = keys.sph_closure(keys.SOLVER_MODULES + ("sph.cases.ldc",))
    assert {"sph.momentum", "sph.riemann", "sph.walls", "sph.solver", "sph.cases.ldc"} <= set(mods)
    assert not set(mods) & keys.NUMBER_NEUTRAL


def _module(root: Path, name: str, text: str):
    path = root.joinpath(*name.split("."))
    path = path / "__init__.py" if name.endswith("!pkg") else path.with_suffix(".py")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_closure_follows_subpackages(tmp_path, monkeypatch):
    root = tmp_path
    for name, text in {"sph.solver": "from .terms import pressure\nfrom . import terms\nfrom .terms.visc import f\n",
                       "sph.simulate": "from lab import io\n", "sph.terms.pressure": "from ..eos import T\n",
                       "sph.terms.visc": "from ..kernels import k\n", "sph.eos": "", "sph.kernels": "",
                       "lab.io": "from sph.state import S\n", "sph.state": "", "lab.study":
                       "from sph.cases import tgv\nfrom . import runs\n", "lab.runs": "", "sph.cases.tgv": ""}.items():
        _module(root, name, text)
    for pkg in ("sph/terms", "lab", "sph/cases", "sph"):
        (root / pkg / "__init__.py").write_text("")
    monkeypatch.setattr(keys, "ROOT", root)
    assert keys.sph_closure(keys.SOLVER_MODULES) == ["sph.eos", "sph.kernels", "sph.simulate", "sph.solver",
                                                     "sph.terms", "sph.terms.pressure", "sph.terms.visc"]
    # a study module of the harness that sets up scenes counts; the run bookkeeping it imports does not
    assert keys.sph_closure(["lab.study"]) == ["lab.study", "sph.cases", "sph.cases.tgv"]


def test_number_neutral_names_harness_modules():
    harness = {f"lab.{p.stem}" for p in (ROOT / "lab").glob("*.py") if p.stem != "__init__"}
    assert keys.NUMBER_NEUTRAL <= harness | {"lab", "sph.xla_cpu"}
    assert {"lab.io", "lab.runs", "lab.cli", "lab.animate"} <= keys.NUMBER_NEUTRAL
    # the studies' set-up and runs can change numbers: a TGV run's key covers them
    studies = {"lab.study"}
    assert not studies & keys.NUMBER_NEUTRAL
    tgv2d = ROOT / "experiments" / "tgv2d"
    assert studies | {"sph.cases.tgv", "sph.relax"} <= set(keys.code_modules([tgv2d / "study.py"]))


def _imported(path: Path) -> list:
    """The absolute module names `path` imports."""
    mods = []
    for node in ast.walk(ast.parse(path.read_text())):
        mods += [a.name for a in node.names] if isinstance(node, ast.Import) else \
            [node.module or ""] if isinstance(node, ast.ImportFrom) and not node.level else []
    return mods


def test_no_study_imports_another():
    """An experiment folder imports only its own modules, the core, the harness and (experiments/sitl
    alone) its library sitl/; the library imports no experiment folder."""
    folders = [p for p in (ROOT / "experiments").iterdir() if p.is_dir()] + [ROOT / n for n in ("gradcheck", "inverse")]
    for folder in folders:
        for path in folder.glob("*.py"):
            for mod in _imported(path):
                top = mod.split(".")[0]
                other = mod.split(".")[1] if top == "experiments" and "." in mod else top
                assert top not in ("experiments", "gradcheck", "inverse", "sitl") or other == folder.name, \
                    f"{path.relative_to(ROOT)}: imports {mod}"
    for path in (ROOT / "sitl").glob("*.py"):
        assert not [m for m in _imported(path) if m.split(".")[0] in ("experiments", "gradcheck", "inverse")], path


def test_core_never_imports_the_harness():
    """sph/ holds no run bookkeeping: no module of it imports lab (nor anything outside sph but
    libraries), and `import sph` in a fresh process loads no lab module."""
    for path in (ROOT / "sph").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and not node.level:
                assert (node.module or "").split(".")[0] not in ("lab", "experiments", "sitl", "report"), \
                    f"{path}: imports {node.module}"
            elif isinstance(node, ast.Import):
                assert not any(a.name.split(".")[0] == "lab" for a in node.names), path
    out = subprocess.run([sys.executable, "-c", "import sys, sph; print(sorted(m for m in sys.modules "
                          "if m == 'lab' or m.startswith('lab.')))"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr


def test_file_keys_ignore_docstrings_and_comments(tmp_path, monkeypatch):
    """Every code key is an AST digest: SitL's training key (sitl.settings.train_fingerprint) too."""
    from sitl import settings as sitl_settings

    copy = tmp_path / "sitl"
    shutil.copytree(ROOT / "sitl", copy, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(sitl_settings, "HERE", copy)
    exp = sitl_settings.load("smoke")
    before = sitl_settings.train_fingerprint(exp, "gns", "{}")
    _edit_docstring(copy / "model.py")
    assert sitl_settings.train_fingerprint(exp, "gns", "{}") == before
    (copy / "train.py").write_text((copy / "train.py").read_text() + "\nEXTRA = 1\n")
    assert sitl_settings.train_fingerprint(exp, "gns", "{}") != before


def test_sitl_dataset_prerequisites_are_its_code_closure(capsys):
    """sitl/rules.mk makes the dataset depend on `python3 -P lab/keys.py generate.py rpf_data.py`:
    the generator, the dataset's settings, the RPF case and the solver's modules, not the file formats
    nor the whole of sph/ (and the same files as sitl.settings.data_fingerprint hashes)."""
    files = [ROOT / "sitl" / "generate.py", ROOT / "sitl" / "rpf_data.py"]
    keys.main([str(f) for f in files])
    listed = set(capsys.readouterr().out.split())
    assert {"sitl/generate.py", "sph/cases/rpf.py", "sph/solver.py", "sph/rollout.py"} <= listed
    assert not {"lab/io.py", "lab/animate.py", "sph/cases/ldc.py"} & listed
    assert "$(shell python3 -P lab/keys.py $(SITL)/generate.py $(SITL)/rpf_data.py" in \
        (ROOT / "sitl" / "rules.mk").read_text()
    assert 'code_fingerprint([HERE / "generate.py", HERE / "rpf_data.py"])' in (ROOT / "sitl" / "settings.py").read_text()


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
    n_frames = io.read_metadata(sp.meta_path)["sequence_length"]
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

    rec = record.record(sp.folder, experiment="tgv2d", target="fig5", method="sph", errors={"e_kin": 0.1})
    assert list(rec)[:len(record.RECORD_COLUMNS)] == list(record.RECORD_COLUMNS)
    assert rec["n_particles"] == 100 and rec["dim"] == 2 and rec["err_e_kin"] == 0.1
    assert rec["n_steps"] == round(0.02 / _solver().dt) and rec["wall_s"] > 0 and rec["peak_rss_mb"] > 0
    assert rec["other_load"] >= 0.0  # measured (Linux), a number of cores, never negative


def test_damaged_metrics_table_names_its_file(tmp_path):
    bad = tmp_path / "metrics.csv"
    bad.write_bytes(b"")
    with pytest.raises(RuntimeError, match=r"metrics\.csv: damaged metrics table"):
        tables.read_table(bad)


def test_select_refuses_values_outside_the_config():
    assert cli.select("--dx", [0.05], [0.05, 0.04]) == [0.05]
    assert cli.select("--dx", None, [0.05]) is None
    with pytest.raises(sph.ConfigError, match=r"--dx 0\.03: not one of this profile's values"):
        cli.select("--dx", [0.03], [0.05, 0.04])


def test_stamp_changes_only_with_the_outputs(tmp_path):
    d = tmp_path / "out"
    d.mkdir()
    (d / "metadata.json").write_text("{}")
    st = d / "runs.done"
    assert stamp.update(st, d)
    assert not stamp.update(st, d)
    (d / "metrics.csv").write_text("a\n1\n")  # a metrics table is an output: a rewritten one counts
    assert stamp.update(st, d)
    assert not stamp.update(st, d)
    (d / "metadata.json").write_text('{"n_steps": 3}')
    assert stamp.update(st, d)
    (d / "run.log").write_text("x")  # logs and set-aside copies do not count
    (d / "traj.h5.stale-0").write_text("x")
    assert not stamp.update(st, d)


# -- a copied folder is an experiment of its own ------------------------------------------------------
def test_copied_experiment_folder_runs_unchanged(tmp_path):
    study = copied_experiment("tgv2d", tmp_path / "my_study", dx=[0.1], t_end=0.05, frames=5, eval_times=[0.05],
                              methods=[{"name": "tvf", "effects": {"tvf": True}}],
                              relaxation={"steps": 20, "quench_every": 10})
    results = tmp_path / "results"
    env_cmd = [sys.executable, "-m", "lab.experiment", str(study), "--profile", "smoke", "--results", str(results),
               "--no-progress"]
    subprocess.run(env_cmd, check=True, cwd=tmp_path, capture_output=True, text=True)
    table = pd.read_csv(results / "my_study" / "metrics.csv")
    assert list(table["method"]) == ["tvf"] and table["n_particles"].tolist() == [100]
    assert (results / "my_study" / "tvf_dx0.1" / "record.json").exists()
    subprocess.run([sys.executable, str(study / "plot_fig5.py"), "--profile", "smoke", "--results", str(results),
                    "--out", str(results / "my_study" / "fig5")], check=True, cwd=tmp_path, capture_output=True)
    assert (results / "my_study" / "fig5" / "fig5.png").stat().st_size > 0
    # nothing was written into the repository's own tgv2d results
    assert not (results / "tgv2d").exists()


_COMPUTE_STUDY = '''
from dataclasses import dataclass
CALLS = []

@dataclass(frozen=True)
class Settings:
    values: tuple[int, ...] = (1, 2)

@dataclass(frozen=True)
class Run:
    name: str
    value: int

def runs(s):
    return [Run(f"v{v}", v) for v in s.values]

def scene(run):
    raise AssertionError("a computed run builds no scene")

def compute(run, folder, progress):
    CALLS.append(run.name)
    return {"square": run.value ** 2}

def metrics(run, traj):
    return {"run": run.name, "err_square": traj["result"]["square"]}
'''


def _compute_folder(tmp_path, extra: str = ""):
    folder = tmp_path / "calc"
    folder.mkdir()
    (folder / "study.py").write_text(_COMPUTE_STUDY + extra)
    (folder / "config.yaml").write_text("profiles:\n  smoke: {values: [1, 2]}\n")
    return folder


@pytest.mark.parametrize("always", [False, True])
def test_a_computed_run_is_cached_unless_its_compute_keeps_its_own_cache(tmp_path, always):
    """A study's `compute` is skipped while its result.json holds the run's key; with COMPUTE = "always"
    (experiments/sitl: the library's trainings keep keys of their own) it is called on every run step,
    and the table is the same either way."""
    from lab.experiment import Experiment

    folder = _compute_folder(tmp_path, '\nCOMPUTE = "always"\n' if always else "")
    exp = Experiment(folder, "smoke", tmp_path / "results")
    first = exp.run_all(progress=False)
    second = exp.run_all(progress=False)
    assert exp.study.CALLS == (["v1", "v2"] * 2 if always else ["v1", "v2"])
    assert list(first["err_square"]) == list(second["err_square"]) == [1, 4]


def test_a_bad_compute_mode_is_named(tmp_path):
    from lab.configtools import ConfigError
    from lab.experiment import Experiment

    with pytest.raises(ConfigError, match=r"COMPUTE.*'always'.*'sometimes'"):
        Experiment(_compute_folder(tmp_path, '\nCOMPUTE = "sometimes"\n'), "smoke", tmp_path / "results")


def test_a_steps_tables_are_those_of_its_own_runs(tmp_path):
    """A step that runs some runs (a group's, `--only`) writes the tables those runs go to and no other
    (experiments/sitl: the table1 step does not rewrite fig3_runs.csv, so its stamp changes only with
    its own runs); a step of every run writes every table."""
    from lab.experiment import Experiment

    folder = _compute_folder(tmp_path, '\nfrom lab.protocol import Table\n'
                                       'TABLE = Table(rows="metrics", file=lambda r: "odd.csv" if r.value % 2 else "even.csv")\n')
    exp = Experiment(folder, "smoke", tmp_path / "results")
    table = exp.run_all(only=["v1"], progress=False)
    assert list(table["run"]) == ["v1"] and (exp.out_dir / "odd.csv").exists() and not (exp.out_dir / "even.csv").exists()
    exp.run_all(progress=False)
    assert pd.read_csv(exp.out_dir / "even.csv")["run"].tolist() == ["v2"]
