"""Nothing destroyed without asking, and make refuses what it cannot do (issue 38): `make clean`
lists and deletes only with FORCE=1, never the paper / cpu profiles by accident; an unknown target
such as `make tests` and a RESULTS path with a space are refused in one line with exit 2."""
import subprocess
import sys

from sph_test_helpers import ROOT

CLEAN = [sys.executable, str(ROOT / "scripts" / "clean.py")]


def _make(*args):
    return subprocess.run(["make", *args], cwd=ROOT, capture_output=True, text=True, timeout=120)


def _profile(root, name):
    (root / name / "fig5" / "run").mkdir(parents=True)
    (root / name / "fig5" / "run" / "traj.h5").write_bytes(b"x" * 5000)
    return root / name


def test_clean_lists_and_deletes_only_with_force(tmp_path):
    smoke = _profile(tmp_path, "smoke")
    out = subprocess.run(CLEAN + ["smoke", "--root", str(tmp_path)], capture_output=True, text=True)
    assert out.returncode == 0 and "nothing deleted: add FORCE=1" in out.stdout and "4.9 KB" in out.stdout
    assert smoke.exists()
    out = subprocess.run(CLEAN + ["smoke", "--root", str(tmp_path), "--force"], capture_output=True, text=True)
    assert out.returncode == 0 and not smoke.exists()


def test_clean_refuses_the_expensive_profiles_without_their_own_target(tmp_path):
    paper = _profile(tmp_path, "paper")
    out = subprocess.run(CLEAN + ["paper", "--root", str(tmp_path), "--force"], capture_output=True, text=True)
    assert out.returncode == 2 and "make clean-expensive PROFILE=paper FORCE=1" in out.stderr
    assert paper.exists()
    out = subprocess.run(CLEAN + ["paper", "--root", str(tmp_path), "--force", "--expensive"], capture_output=True,
                         text=True)
    assert out.returncode == 0 and not paper.exists()


def test_make_clean_without_force_deletes_nothing_and_is_in_help():
    before = sorted(p.name for p in (ROOT / "results").glob("*")) if (ROOT / "results").exists() else []
    out = _make("clean")
    assert out.returncode == 0, out.stderr
    after = sorted(p.name for p in (ROOT / "results").glob("*")) if (ROOT / "results").exists() else []
    assert before == after
    assert "make clean" in _make("help").stdout


def test_unknown_targets_and_a_spaced_results_path_are_refused():
    for target in ("tests", "figure5"):
        out = _make(target)
        assert out.returncode == 2 and "make help lists the targets" in out.stderr, (target, out.stderr)
    out = _make("help", "RESULTS=my results")
    assert out.returncode == 2 and "holds a space" in out.stderr


def test_the_atlas_waits_for_the_experiments_asked_beside_it():
    """`make -j2 fig9 accuracy` after a tgv3d change kept the old tgv3d rows: the atlas rule did not
    depend on the other targets. Now every target asked beside it is an order-only prerequisite of the
    atlas (make's own database shows it), and the atlas asked alone runs no experiment."""
    def atlas_rule(*goals):
        out = subprocess.run(["make", "-p", "-n", *goals, "PROFILE=smoke", "RESULTS=/tmp/sph-guard"], cwd=ROOT,
                             capture_output=True, text=True, timeout=120).stdout
        return next(line for line in out.splitlines() if line.startswith("/tmp/sph-guard/accuracy/runs.csv:") and "runs.done" in line)

    assert "| .venv/.stamp fig9" in atlas_rule("fig9", "accuracy")
    assert atlas_rule("accuracy").rstrip().endswith("| .venv/.stamp")


def test_the_report_waits_for_the_targets_asked_beside_it():
    """`make -j2 fig5 report` could build the report before fig5's figure: now every target asked
    beside it is an order-only prerequisite of the report (make's own database shows it)."""
    out = subprocess.run(["make", "-p", "-n", "fig5", "report", "PROFILE=smoke", "RESULTS=/tmp/sph-guard"], cwd=ROOT,
                         capture_output=True, text=True, timeout=120).stdout
    rule = next(line for line in out.splitlines() if line.startswith("report:"))
    assert "| .venv/.stamp fig5" in rule
