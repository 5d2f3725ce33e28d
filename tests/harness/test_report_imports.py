"""report/: its modules import each other without a circle, counting the imports made inside
functions too (a lazy import only hides a circle). A circle means two modules each need the other's
names, so neither can be read, tested or moved alone."""
import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "report"


def _imports(path: Path) -> set:
    """The report modules `path` imports anywhere in its body (relative or `report.` imports)."""
    mods = {p.stem for p in PACKAGE.glob("*.py")}
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level == 1 or base.startswith("report"):
                base = base.removeprefix("report").lstrip(".")
                if base:
                    out.add(base.split(".")[0])
                else:  # from . import a, b
                    out |= {a.name for a in node.names}
        elif isinstance(node, ast.Import):
            out |= {a.name.split(".")[1] for a in node.names if a.name.startswith("report.")}
    return (out & mods) - {path.stem}


def _cycle(graph: dict):
    """A cycle of `graph` as a list of nodes, or None."""
    state = {}

    def visit(n, stack):
        state[n] = "open"
        for m in sorted(graph.get(n, ())):
            if state.get(m) == "open":
                return stack[stack.index(m):] + [m]
            if m not in state:
                found = visit(m, stack + [m])
                if found:
                    return found
        state[n] = "done"
        return None

    for n in sorted(graph):
        if n not in state:
            found = visit(n, [n])
            if found:
                return found
    return None


def test_the_report_modules_import_each_other_without_a_circle():
    graph = {p.stem: _imports(p) for p in PACKAGE.glob("*.py") if p.stem != "__init__"}
    assert graph["readme_walls"] >= {"readme_cells"}, graph["readme_walls"]  # the graph is read at all
    assert _cycle(graph) is None, " -> ".join(_cycle(graph))


def test_the_cycle_finder_finds_a_circle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None
