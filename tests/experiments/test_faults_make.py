"""Issue 23 class 1: what `make` hands over is made from exactly the current runs, checked on every make.

One mechanism for every deliverable rule (lab.deliver, fed by the run stamps of
lab.stamp): removing a method or a dx from a profile re-makes the figure and its table with
exactly the remaining runs (the removed runs' folders stay on disk: nothing finished is lost), a
truncated metrics.csv or a deleted figure is made again, and a make with nothing changed re-makes
nothing. Run through `make` itself, on copies of the experiment folders (the Makefile's folder
variables point at the copy), for the TGV (fig5), cavity (fig6) and atlas (accuracy) targets.
Smoke sizes: 64-100 particles, a few dozen steps.
"""
import json
import shutil
import subprocess
from pathlib import Path

import pandas as pd
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]


def copy_experiment(name: str, dest: Path, **smoke) -> Path:
    """experiments/<name> copied to `dest`, its smoke profile's keys `smoke` replaced."""
    shutil.copytree(ROOT / "experiments" / name, dest, ignore=shutil.ignore_patterns("__pycache__"))
    set_smoke(dest, **smoke)
    return dest


def set_smoke(folder: Path, **smoke) -> None:
    cfg = yaml.safe_load((folder / "config.yaml").read_text())
    cfg["profiles"]["smoke"].update(smoke)
    (folder / "config.yaml").write_text(yaml.safe_dump(cfg))


def make(results: Path, *targets, makefiles=(), **variables) -> subprocess.CompletedProcess:
    cmd = ["make", "--no-print-directory", "-f", "Makefile", *[a for f in makefiles for a in ("-f", str(f))],
           "PROFILE=smoke", f"RESULTS={results}", *[f"{k}={v}" for k, v in variables.items()], *map(str, targets)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return proc


def rows(path) -> list:
    t = pd.read_csv(path)
    return sorted(zip(t["method"], t["dx"].round(6)))


TGV_SMOKE = dict(dx=[0.125, 0.1], t_end=0.05, frames=5, eval_times=[0.05],
                 methods=[{"name": "sph", "effects": {}}, {"name": "tvf", "effects": {"tvf": True}}],
                 relaxation={"steps": 20, "quench_every": 10})


# -- TGV: fig5 ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tgv(tmp_path_factory):
    """A copy of tgv2d (`make <its fig5>`: the protocol's rules for the folder, its rules.mk's figure folders), made once."""
    tmp = tmp_path_factory.mktemp("tgv")
    study = copy_experiment("tgv2d", tmp / "study", **TGV_SMOKE)
    results = tmp / "results"
    fig5 = results / "study" / "fig5"

    def run():
        return make(results, fig5 / "fig5.png", PROTOCOL_DIRS=study)

    run()
    return study, results, fig5, run


def test_fig5_is_made_from_its_runs_and_a_second_make_redoes_nothing(tgv):
    study, results, fig5, run = tgv
    assert rows(fig5 / "metrics.csv") == [("sph", 0.1), ("sph", 0.125), ("tvf", 0.1), ("tvf", 0.125)]
    manifest = json.loads((results / "study" / "runs.done").read_text())
    assert sorted(manifest["outputs"]) == ["metrics.csv", "sph_dx0.1", "sph_dx0.125", "tvf_dx0.1", "tvf_dx0.125"]
    before = {p.name: p.stat().st_mtime_ns for p in fig5.iterdir()}
    out = run().stdout
    assert "current outputs unchanged" in out and "fig5.pdf, metrics.csv}: up to date with its runs" in out
    assert "fig5 ->" not in out  # the plot script did not run
    assert {p.name: p.stat().st_mtime_ns for p in fig5.iterdir()} == before


def test_truncated_figure_table_and_deleted_figure_are_made_again(tgv):
    study, results, fig5, run = tgv
    table = fig5 / "metrics.csv"
    table.write_text(table.read_text()[:60])  # truncated mid-row
    out = run().stdout
    assert f"{table}: making" not in out and "metrics.csv differs from what was made (damaged or edited)" in out
    assert rows(table) == [("sph", 0.1), ("sph", 0.125), ("tvf", 0.1), ("tvf", 0.125)]
    (fig5 / "fig5.pdf").unlink()
    out = run().stdout
    assert "fig5.pdf is missing" in out and (fig5 / "fig5.pdf").stat().st_size > 0
    assert "complete, skipped" in out and "steps of" not in out  # no run was redone for it


def test_removed_dx_and_method_leave_the_figure_and_come_back_without_rerunning(tgv):
    study, results, fig5, run = tgv
    set_smoke(study, dx=[0.125], methods=[TGV_SMOKE["methods"][1]])
    out = run().stdout
    assert "current outputs changed" in out and "runs.done changed" in out
    assert rows(fig5 / "metrics.csv") == [("tvf", 0.125)]
    assert rows(results / "study" / "metrics.csv") == [("tvf", 0.125)]
    assert sorted(json.loads((results / "study" / "runs.done").read_text())["outputs"]) == ["metrics.csv", "tvf_dx0.125"]
    for name in ("sph_dx0.1", "sph_dx0.125", "tvf_dx0.1"):  # nothing finished is lost
        assert (results / "study" / name / "traj.h5").is_file()
    set_smoke(study, **TGV_SMOKE)
    out = run().stdout
    assert out.count("complete, skipped") == 4 and "steps of" not in out
    assert rows(fig5 / "metrics.csv") == [("sph", 0.1), ("sph", 0.125), ("tvf", 0.1), ("tvf", 0.125)]


def test_a_failed_plot_leaves_no_record_so_the_next_make_retries(tgv, tmp_path):
    """The manifest is removed before the script runs and written only after it succeeded."""
    from lab import deliver

    study, results, fig5, _ = tgv
    outs = [str(fig5 / "fig5.png"), str(fig5 / "fig5.pdf"), str(fig5 / "metrics.csv")]
    inputs = [str(results / "study" / "runs.done")]
    assert deliver.why_remake(outs, inputs, ["true"]) == "its command changed"
    assert deliver.make(outs, inputs, ["false"]) == 1
    assert deliver.read_manifest(outs) is None
    assert deliver.why_remake(outs, inputs, ["false"]).startswith("no record of how it was made")


# -- cavity: fig6 ---------------------------------------------------------------------------------------
def test_fig6_table_is_exactly_the_current_methods(tmp_path):
    methods = yaml.safe_load((ROOT / "experiments" / "ldc2d" / "config.yaml").read_text())["profiles"]["paper"]["methods"]
    assert len(methods) >= 2
    methods = methods[:2]  # two of the paper's methods: one to remove, one to keep
    ldc = copy_experiment("ldc2d", tmp_path / "ldc2d", figures={"fig6": 0.05}, t_end=0.05, frames=2,
                          analysis={"average_frames": 2, "steady_window": 0.02}, methods=methods)
    results = tmp_path / "results"
    fig6 = results / "fig6" / "fig6.png"
    make(results, fig6, PROTOCOL_DIRS=ldc)
    names = [m["name"] for m in methods]
    assert sorted(m for m, _ in rows(results / "fig6" / "metrics.csv")) == sorted(names)
    set_smoke(ldc, methods=methods[:1])
    out = make(results, fig6, PROTOCOL_DIRS=ldc).stdout
    assert "fig6_runs.done changed" in out
    assert [m for m, _ in rows(results / "fig6" / "metrics.csv")] == [names[0]]
    assert (results / "ldc2d" / f"{names[1]}_dx0.05" / "traj.h5").is_file()  # kept on disk
    out = make(results, fig6, PROTOCOL_DIRS=ldc).stdout
    assert "up to date with its runs" in out


# -- the atlas: accuracy --------------------------------------------------------------------------------
def test_atlas_rows_are_exactly_the_current_runs(tmp_path):
    exps = tmp_path / "experiments"
    copy_experiment("tgv2d", exps / "tgv2d", relaxation={"steps": 20, "quench_every": 10})
    acc = copy_experiment("accuracy", exps / "accuracy", gather=[],
                          tgv={"base_profile": "smoke", "methods": ["tvf"], "dx": [0.125, 0.1], "dtypes": ["float64"],
                               "kernels": ["quintic"], "t_end": 0.05, "frames": 5, "error": "u_max_mean"})
    results = tmp_path / "results"
    make(results, "accuracy", PROTOCOL_DIRS=acc)
    table = results / "accuracy" / "runs.csv"
    assert sorted(pd.read_csv(table)["dx"].round(6)) == [0.1, 0.125]
    cfg = yaml.safe_load((acc / "config.yaml").read_text())
    cfg["profiles"]["smoke"]["tgv"]["dx"] = [0.125]
    (acc / "config.yaml").write_text(yaml.safe_dump(cfg))
    out = make(results, "accuracy", PROTOCOL_DIRS=acc).stdout
    assert "runs.done changed" in out
    assert sorted(pd.read_csv(table)["dx"].round(6)) == [0.125]  # the dx 0.1 record is still on disk, not listed
    assert list((results / "accuracy").rglob("tvf_dx0.1/record.json"))
    table.write_text("experiment\n")  # truncated
    out = make(results, "accuracy", PROTOCOL_DIRS=acc).stdout
    assert "runs.csv differs from what was made" in out and len(pd.read_csv(table)) == 1
    out = make(results, "accuracy", PROTOCOL_DIRS=acc).stdout
    assert "up to date with its runs" in out
