"""Issue 23, harness side of classes 2, 4, 5 and 7: cached inputs checked against what they were made
for, one line and an exit code for every error, the keys that disagree named with the changed one
first, names that stay inside their folder, memory refused before anything is built, set-aside copies
bounded. Mostly in-process; smoke sizes where a solver is needed.
"""
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

from sph.errors import ConfigError
from lab import cli, io, runs
from lab.cli import EXIT_CONFIG, EXIT_INTERRUPTED, EXIT_OUTPUT, main_guard
from lab.configtools import load_yaml
from lab.experiment import Experiment, load_settings
from lab.layout import Study

ROOT = Path(__file__).resolve().parents[2]


def guarded(fn, capsys):
    """(exit code, stderr lines) of `fn` run through main_guard."""
    with pytest.raises(SystemExit) as e:
        main_guard(fn)
    return e.value.code, capsys.readouterr().err.strip().splitlines()


# -- class 4: one line and an exit code --------------------------------------------------------------
@pytest.mark.parametrize("text, line, what", [
    ("profiles:\n  paper:\n    dx: [0.1, 0.2\n    t_end: 1\n", 4, r"expected ',' or '\]'.*started at line 3"),
    ("profiles:\n  paper:\n\tdx: 0.1\n", 3, r"found character '\\t'.*never tabs"),
    ("profiles:\n  paper: {dx: 0.1\n", 3, r"flow mapping"),
    ("profiles:\n  paper:\n    dx: 'open\n", 4, r"quoted scalar"),
])
def test_yaml_syntax_errors_are_one_line_naming_file_and_line(tmp_path, capsys, text, line, what):
    cfg = tmp_path / "config.yaml"
    cfg.write_text(text)
    code, err = guarded(lambda: load_yaml(cfg), capsys)
    assert code == EXIT_CONFIG and len(err) == 1
    assert err[0].startswith(f"error (config error): {cfg}:{line}: YAML syntax error: ")
    import re
    assert re.search(what, err[0]), err[0]


def test_a_script_with_a_tab_in_its_config_prints_one_line(tmp_path):
    study = tmp_path / "study"
    shutil.copytree(ROOT / "experiments" / "tgv2d", study, ignore=shutil.ignore_patterns("__pycache__"))
    text = (study / "config.yaml").read_text().replace("    dx: [0.05, 0.04]", "\tdx: [0.05, 0.04]")
    (study / "config.yaml").write_text(text)
    p = subprocess.run([sys.executable, "-m", "lab.experiment", str(study), "--profile", "smoke", "--results",
                        str(tmp_path / "r")],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == EXIT_CONFIG and p.stderr.strip().count("\n") == 0, p.stderr
    assert f"{study / 'config.yaml'}:" in p.stderr and "never tabs" in p.stderr and "Traceback" not in p.stderr


def test_ctrl_c_is_one_line_and_exit_130(capsys):
    def interrupted():
        raise KeyboardInterrupt

    code, err = guarded(interrupted, capsys)
    assert code == EXIT_INTERRUPTED == 130 and len(err) == 1
    assert err[0].startswith("interrupted: ") and err[0].endswith("resume with the same command")


def test_ctrl_c_outside_main_guard_is_one_line(capsys):
    from lab import interrupt

    interrupt._excepthook(KeyboardInterrupt, KeyboardInterrupt(), None)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("interrupted: ")


def test_damaged_trajectory_names_the_file_exit_4(tmp_path, capsys):
    traj = tmp_path / "sph_dx0.1" / "traj.h5"
    traj.parent.mkdir()
    traj.write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 40)  # a truncated HDF5 file
    code, err = guarded(lambda: io.read_trajectory(traj), capsys)
    assert code == EXIT_OUTPUT and len(err) == 1
    assert err[0].startswith(f"error (damaged file): {traj}: cannot read trajectory")


def test_damaged_metrics_table_names_the_file_exit_4(tmp_path, capsys):
    from lab import tables

    t = tmp_path / "metrics.csv"
    t.write_bytes(b"\x00\xff\x00garbage")
    code, err = guarded(lambda: tables.read_table(t), capsys)
    assert code == EXIT_OUTPUT and len(err) == 1 and err[0].startswith(f"error (damaged file): {t}: damaged metrics table")


@pytest.mark.parametrize("argv, option", [
    (["--only"], "--only"), (["--dx"], "--dx"), (["--only", "--dx", "0.05"], "--only"),
])
def test_an_option_without_its_value_is_an_error_not_run_nothing(capsys, argv, option):
    with pytest.raises(SystemExit) as e:
        cli.profile_args(None, argv, cli.run_options("--dx", float, "spacings"))
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == EXIT_CONFIG and len(err) == 1
    assert err[0].startswith("error (usage): ") and f"{option} needs at least one value" in err[0]


def test_unknown_option_is_one_line(capsys):
    with pytest.raises(SystemExit) as e:
        cli.profile_args(None, ["--olny", "tvf"])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == EXIT_CONFIG and len(err) == 1 and "unrecognized arguments: --olny" in err[0]


def test_select_refuses_an_empty_subset():
    with pytest.raises(ConfigError, match=r"--only: given without a value"):
        cli.select("--only", [], ["sph", "tvf"])


# -- class 5: the keys that disagree, the changed one first --------------------------------------------
def _load(folder):
    """settings.load of an experiment folder (a fresh module each time); of a folder of the protocol
    (a study.py), lab.experiment.load_settings of it as `.load`."""
    import functools
    import importlib.util
    import types

    if (folder / "study.py").exists():
        from lab.experiment import load_settings

        return types.SimpleNamespace(load=functools.partial(load_settings, folder))
    spec = importlib.util.spec_from_file_location(f"settings_{folder.name}_{time.time_ns()}", folder / "settings.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture()
def committed_ldc(tmp_path):
    """ldc2d's study and config in a git repository of their own, committed."""
    repo = tmp_path / "repo"
    folder = repo / "ldc2d"
    shutil.copytree(ROOT / "experiments" / "ldc2d", folder, ignore=shutil.ignore_patterns("__pycache__"))
    git = ["git", "-C", str(repo), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    subprocess.run(git + ["add", "."], check=True)
    subprocess.run(git + ["commit", "-q", "-m", "c"], check=True)
    return folder


def _edit(folder, fn):
    cfg = yaml.safe_load((folder / "config.yaml").read_text())
    fn(cfg["profiles"]["paper"])
    (folder / "config.yaml").write_text(yaml.safe_dump(cfg))


def test_changed_ghia_re_is_blamed_not_eta(committed_ldc):
    _edit(committed_ldc, lambda p: p.update(ghia_re=400))
    with pytest.raises(ConfigError) as e:
        load_settings(committed_ldc, "smoke")
    msg = str(e.value)
    assert e.value.key == "ghia_re"
    assert "profiles.paper.ghia_re: Re = rho_ref lid_velocity / eta = 100 differs from ghia_re = 400" in msg
    assert "(the keys that disagree: ghia_re = 400 (changed since the last commit); material.eta = 0.01" in msg


def test_changed_eta_is_blamed_not_ghia_re(committed_ldc):
    _edit(committed_ldc, lambda p: p["material"].update(eta=0.0025))
    with pytest.raises(ConfigError) as e:
        load_settings(committed_ldc, "paper")
    assert e.value.key == "material.eta"
    assert "disagree: material.eta = 0.0025 (changed since the last commit); ghia_re = 100" in str(e.value)


def test_changed_cube_size_is_blamed_not_the_origin():
    inv = _load(ROOT / "inverse")
    with pytest.raises(ConfigError) as e:
        inv.load("paper", overrides={"cube_size": 0.8})
    assert e.value.key == "cube_size"
    assert "(the keys that disagree: cube_size = 0.8 (set on the command line); cases[0].origin = " in str(e.value)


def test_changed_dx_is_named_with_cube_size():
    inv = _load(ROOT / "inverse")
    with pytest.raises(ConfigError) as e:
        inv.load("paper", overrides={"dx": 0.07})
    assert e.value.key == "dx" and "cube_size = 0.3" in str(e.value)


# -- class 7: names, memory, set-aside copies -----------------------------------------------------------
@pytest.mark.parametrize("name", ["a/../../x", "../up", "with space", "", "1st", "a.b"])
def test_method_names_are_identifiers(name):
    with pytest.raises(ConfigError, match=r"methods\[0\]\.name: .* is not a name: it becomes a folder name"):
        load_settings(ROOT / "experiments" / "tgv2d", "smoke", overrides={"methods": [{"name": name}]})


def test_stability_case_names_are_identifiers():
    with pytest.raises(ConfigError, match=r"cases\.a/\.\./x: 'a/\.\./x' is not a name"):
        load_settings(ROOT / "experiments" / "stability", "smoke", overrides={"cases": {"a/../x": {}}})


def test_a_run_folder_never_leaves_its_study(tmp_path):
    with pytest.raises(ConfigError, match=r"method name: 'a/\.\./\.\./x' is not a name"):
        Study("s", tmp_path).run_dir(tmp_path, "a/../../x", "dx0.1")


def test_memory_is_refused_in_seconds_before_anything_is_built(tmp_path, monkeypatch):
    import sph.memory

    monkeypatch.setattr(sph.memory, "available_memory", lambda: (50 * 2**20, "available host memory"))
    exp = Experiment(ROOT / "experiments" / "tgv2d", "smoke", tmp_path, overrides={"dx": [0.1, 0.002]})
    t0 = time.perf_counter()
    with pytest.raises(sph.memory.InsufficientMemory, match=r"tgv2d at dx = 0\.002: 250,000 particles .* use a larger dx"):
        exp.run_all(progress=False)
    assert time.perf_counter() - t0 < 5
    assert not any(tmp_path.rglob("*")), "nothing is relaxed, run or written before the refusal"


def test_set_aside_copies_are_bounded(tmp_path, capsys):
    f = tmp_path / "traj.h5"
    for i in range(6):
        f.write_text(f"v{i}")
        runs.set_aside(f, "made from other inputs")
    kept = sorted(p.name for p in tmp_path.iterdir())
    assert kept == [f"traj.h5.stale-{n}" for n in (3, 4, 5)]
    assert (tmp_path / "traj.h5.stale-5").read_text() == "v5"  # the newest ones stay
    assert "removed older copies traj.h5.stale-2" in capsys.readouterr().out


# -- class 2: cached inputs carry and check what they were made for --------------------------------------
def _cache(path, dx, n, calls):
    def compute():
        calls.append(dx)
        return np.full((n, 2), dx), {"steps": 1}
    return runs.cached_positions(path, f"fp{dx}", compute, "relaxed", dx=dx)


def test_relaxed_cache_of_another_dx_is_set_aside_and_redone(tmp_path, capsys):
    calls = []
    path = tmp_path / "relaxed_dx0.1.npy"
    _cache(path, 0.1, 100, calls)
    assert _cache(path, 0.1, 100, calls).shape == (100, 2) and calls == [0.1]  # reused
    shutil.copy(path.with_suffix(".json"), tmp_path / "keep.json")
    # a cache of dx 0.05 (its array and sidecar) copied over this one
    _cache(tmp_path / "other.npy", 0.05, 400, calls)
    shutil.copy(tmp_path / "other.npy", path)
    shutil.copy(tmp_path / "other.json", path.with_suffix(".json"))
    capsys.readouterr()
    r = _cache(path, 0.1, 100, calls)
    out = capsys.readouterr().out.strip().splitlines()
    assert r.shape == (100, 2) and calls == [0.1, 0.05, 0.1]
    assert out[0] == (f"{path}: cached start made for dx = 0.05, not 0.1; kept as relaxed_dx0.1.npy.stale-0, "
                      "computing it again")
    assert (tmp_path / "relaxed_dx0.1.npy.stale-0").exists() and (tmp_path / "relaxed_dx0.1.json.stale-0").exists()


def test_relaxed_cache_with_another_particle_count_or_damaged_is_redone(tmp_path, capsys):
    calls = []
    path = tmp_path / "relaxed_dx0.1.npy"
    _cache(path, 0.1, 100, calls)
    np.save(path, np.zeros((64, 2)))  # the array swapped, the sidecar kept
    assert _cache(path, 0.1, 100, calls).shape == (100, 2) and len(calls) == 2
    assert "holds 64 particles of dimension 2, made for 100 of dimension 2" in capsys.readouterr().out
    path.write_bytes(path.read_bytes()[:100])  # truncated
    assert _cache(path, 0.1, 100, calls).shape == (100, 2) and len(calls) == 3
    assert f"{path}: cached start unreadable" in capsys.readouterr().out


def test_damaged_checkpoint_is_set_aside_and_the_run_redone(tmp_path, capsys):
    from sph.cases import tgv

    exp = Experiment(ROOT / "experiments" / "tgv2d", "smoke", tmp_path,
                     overrides={"dx": [0.1], "t_end": 0.02, "frames": 2, "eval_times": [0.02]})
    run = exp.runs[0]
    sp = exp.spec(run)
    from sph.lattice import cartesian

    r = cartesian([0.0, 0.0], [1.0, 1.0], 0.1)
    from sph import build_solver

    build = lambda: build_solver(*exp.study.scene(run, r))  # noqa: E731
    runs.run_cached(sp, build, progress=False)
    with h5py.File(sp.traj, "a") as f:  # a stopped run whose checkpoint lost a field
        f["00000"].attrs["complete"] = False
        del f["00000/checkpoint/r"]
    assert runs.stored_state(sp) == "partial"
    capsys.readouterr()
    out = runs.run_cached(sp, build, progress=False)
    text = capsys.readouterr().out
    assert out.status == "run" and f"{sp.traj}: damaged checkpoint" in text and "kept as traj.h5.stale-0" in text
    assert runs.stored_state(sp) == "current" and (sp.folder / "traj.h5.stale-0").exists()
    _ = tgv  # the case module the scene comes from


# -- class 3: damaged SitL files (the make-level cases are in test_sitl_pipeline.py / test_sitl_cost.py)
def _fake_checkpoint(folder: Path, step: int = 5) -> None:
    """A checkpoint folder as LagrangeBench's save_haiku writes it: tree pickles, their leaves one
    after another in one .npy file, the optimizer state, the step."""
    import pickle
    folder.mkdir(parents=True)
    for kind, tree in (("params", {"w": np.ones((3, 4)), "b": np.zeros(4)}), ("state", {})):
        (folder / f"{kind}_tree.pkl").write_bytes(pickle.dumps({k: 0 for k in tree}))
        with (folder / f"{kind}_array.npy").open("wb") as f:
            for v in tree.values():
                np.save(f, v)
    (folder / "opt_state.pkl").write_bytes(pickle.dumps({"count": step}))
    (folder / "metadata_ckp.json").write_text(json.dumps({"step": step, "loss": 1.0}))


def test_a_truncated_sitl_checkpoint_is_named_and_its_folder_set_aside(tmp_path, capsys):
    from sitl import integrity

    ckp = tmp_path / "ckp" / "gns"
    _fake_checkpoint(ckp / "best")
    assert integrity.unreadable_checkpoint(ckp / "best") is None
    recorded = integrity.digests(ckp, ["best/params_array.npy", "best/metadata_ckp.json"])
    arr = ckp / "best" / "params_array.npy"
    arr.write_bytes(arr.read_bytes()[:100])
    assert integrity.damaged(ckp, recorded) == (arr, "changed since it was written (truncated?)")
    path, why = integrity.unreadable_checkpoint(ckp / "best")
    assert path == arr and why.startswith("unreadable (")
    integrity.set_aside_damaged(path, why, then="training gns again", whole=ckp)
    line = capsys.readouterr().out.strip()
    assert "\n" not in line and str(arr) in line and "kept as gns.stale-0, training gns again" in line
    assert not ckp.exists() and (tmp_path / "ckp" / "gns.stale-0" / "best" / "params_array.npy").exists()
    (ckp / "best").mkdir(parents=True)                         # the next set-aside folders stay bounded
    for _ in range(runs.KEEP_STALE + 2):
        integrity.set_aside_damaged(ckp / "x", "test", then="again", whole=ckp)
        ckp.mkdir()
    assert len(list((tmp_path / "ckp").glob("gns.stale-*"))) == runs.KEEP_STALE


def test_a_truncated_sitl_split_is_one_line_naming_it(tmp_path):
    """generate.ready (what train / evaluate call) on a split that differs from the digest
    generate.json recorded: OutputError (one line, exit 4 through main_guard) naming the file and
    what repairs it."""
    from sitl import generate
    from sitl import integrity
    from sitl import settings as S

    exp = S.load("smoke")
    path = S.data_dir(tmp_path)
    path.mkdir(parents=True)
    for name in generate.FILES:
        (path / name).write_bytes(b"x" * 1000)
    (path / "generate.json").write_text(json.dumps({
        "config": S.data_config_digest(exp), "fingerprint": S.data_fingerprint(exp),
        "files": integrity.digests(path, generate.FILES)}))
    (path / "test.h5").write_bytes(b"x" * 500)
    with pytest.raises(io.OutputError) as e:
        generate.ready(exp, tmp_path)
    msg = str(e.value)
    assert msg.startswith(f"{path / 'test.h5'}: damaged (changed since it was written") and "make sitl-data" in msg
    assert "\n" not in msg
