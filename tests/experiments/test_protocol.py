"""Every experiment folder follows one protocol (lab.experiment): config.yaml, one study module
(study.py: Settings, runs, scene, metrics; or its metrics in analysis.py, out of the runs' keys) and
its plot scripts (plot_<name>.py); no run or settings
script, no forwarder, no `try: from . import ... / except ImportError` import workaround; its profiles
load through the harness; its rules.mk, if any, holds no recipe (the Makefile's protocol rules make
its runs and figures; a rules.mk only says what is the folder's own: figure folders, target names).

experiments/sitl is one too: its runs compute (a training and an evaluation, or long rollouts) in
LagrangeBench's environment, with the library sitl/ behind them.
"""
import ast
from pathlib import Path

import pytest

from lab.experiment import Experiment

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = sorted([p.relative_to(ROOT).as_posix() for p in (ROOT / "experiments").iterdir()
                  if p.is_dir() and not p.name.startswith((".", "_"))] + ["gradcheck", "inverse"])
"""Every experiment folder of the repository."""

STUDY_NAMES = ("Settings", "runs", "scene", "metrics")


def _defined(path: Path) -> set:
    tree = ast.parse(path.read_text())
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return names


def _import_workaround(path: Path) -> bool:
    """A `try: from . import x / except ImportError: import x` (a script that is also a module)."""
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Try) and any(isinstance(h.type, ast.Name) and h.type.id == "ImportError"
                                             for h in node.handlers):
            return True
    return False


def check_protocol(folder: Path, tmp_path: Path) -> None:
    rel = folder.relative_to(ROOT)
    assert (folder / "config.yaml").is_file(), f"{rel}: no config.yaml"
    assert (folder / "study.py").is_file(), f"{rel}: no study.py"
    defined = _defined(folder / "study.py") | (_defined(folder / "analysis.py") if (folder / "analysis.py").exists() else set())
    missing = [n for n in STUDY_NAMES if n not in defined]
    assert not missing, f"{rel}/study.py: defines no {missing}"
    assert list(folder.glob("plot_*.py")), f"{rel}: no plot_<name>.py"
    scripts = sorted(p.name for p in folder.glob("*.py"))
    assert not {"run.py", "settings.py"} & set(scripts), f"{rel}: a run or settings script beside study.py ({scripts})"
    others = [s for s in scripts if s not in ("study.py", "analysis.py", "__init__.py") and not s.startswith("plot_")]
    assert not others, f"{rel}: modules other than study.py, analysis.py and plot scripts: {others}"
    for p in folder.glob("*.py"):
        assert not _import_workaround(p), f"{rel}/{p.name}: an `except ImportError` import workaround"
    rules = folder / "rules.mk"
    if rules.exists():
        recipes = [line for line in rules.read_text().splitlines() if line.startswith("\t")]
        assert not recipes, f"{rel}/rules.mk: holds recipes (the protocol's rules make them): {recipes[:2]}"
    for profile in ("smoke", "paper"):
        exp = Experiment(folder, profile, tmp_path)
        assert exp.runs, f"{rel}: profile {profile} has no runs"


@pytest.mark.parametrize("name", FOLDERS)
def test_folder_follows_the_protocol(name, tmp_path):
    check_protocol(ROOT / name, tmp_path)


def test_every_folder_is_listed():
    """The SitL experiment is a folder of the protocol like the others (its library sitl/ is not)."""
    assert {"experiments/sitl", "experiments/droplet", "gradcheck", "inverse"} <= set(FOLDERS) and "sitl" not in FOLDERS


def _writes_of_its_own(path: Path) -> list:
    """The file writes of `path` that bypass the harness: the csv module, pandas' to_csv, a
    Path.write_text / write_bytes method, an open() for writing (appending to a log is allowed:
    a half-written last line is dropped on reading)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import) and any(a.name == "csv" for a in node.names):
            found.append(f"line {node.lineno}: import csv")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            name = node.func.attr
            if name in ("to_csv", "DictWriter", "write_text", "write_bytes"):
                found.append(f"line {node.lineno}: .{name}(")
            elif name == "open" and node.args and isinstance(node.args[0], ast.Constant) \
                    and isinstance(node.args[0].value, str) and "w" in node.args[0].value:
                found.append(f"line {node.lineno}: .open({node.args[0].value!r})")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "open" \
                and len(node.args) > 1 and isinstance(node.args[1], ast.Constant) and "w" in str(node.args[1].value):
            found.append(f"line {node.lineno}: open(..., {node.args[1].value!r})")
    return found


def test_sitl_writes_its_tables_and_records_through_the_harness():
    """The SitL library (sitl/, run in LagrangeBench's environment) and its folder write no CSV of their
    own: tables go through lab.tables.write_table, records and pages through lab.atomic.write_text (a
    killed process leaves the old file or the new one, never half of one)."""
    scripts = sorted((ROOT / "sitl").glob("*.py")) + sorted((ROOT / "experiments" / "sitl").glob("*.py"))
    assert len(scripts) > 10
    found = {p.name: w for p in scripts if (w := _writes_of_its_own(p))}
    assert not found, found


def test_the_write_check_finds_a_private_writer(tmp_path):
    p = tmp_path / "w.py"
    p.write_text("import csv\nfrom pathlib import Path\nPath('a').write_text('x')\nopen('b', 'w')\n"
                 "Path('c').open('a')\nimport pandas as pd\npd.DataFrame().to_csv('d')\n")
    assert [w.split(":")[1].strip() for w in _writes_of_its_own(p)] == \
        ["import csv", ".write_text(", "open(..., 'w')", ".to_csv("]
