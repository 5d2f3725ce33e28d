"""Cache keys: what identifies the inputs of a result, so that a cached one is reused exactly when
they are the same.

`digest(obj)` hashes a JSON-able object (a config through `configtools.to_mapping`).
`code_fingerprint(files, modules)` hashes the code behind a run: the solver's modules (the `sph`
modules the solver and the driver import, transitively, into subpackages too), the `sph` modules
the experiment's own `files` import (its case module, a study module of the harness, ...) and those
files, each parsed and hashed without docstrings and comments (`code_digest`). The number-neutral
modules (`NUMBER_NEUTRAL`: file formats, run bookkeeping, the command line) and what only they
import stay out, so editing a docstring, `lab/io.py`, a plot script or another experiment
re-runs nothing, while editing `sph/momentum.py` re-runs every run whose solver imports it.
"""
import ast
import functools
import hashlib
import json
import sys
from pathlib import Path
from typing import Iterable, Optional

ROOT = Path(__file__).resolve().parents[1]
"""The folder holding the packages whose modules a key follows (PACKAGES)."""
PACKAGES = ("sph", "lab")
"""The core and the harness: a run's key covers the modules of these its code imports."""

NUMBER_NEUTRAL = frozenset({
    "lab", "lab.animate", "lab.atomic", "lab.cli", "lab.configtools", "lab.io",
    "lab.keys", "lab.layout", "lab.other_load", "lab.record", "lab.runs",
    "lab.stamp", "lab.interrupt", "lab.typed", "lab.yamlfile", "lab.profiles",
    "lab.tables", "lab.xdmf", "sph.xla_cpu", "lab.deliver", "lab.figures", "lab.protocol"})
"""Modules that cannot change a run's numbers: file formats, bookkeeping, paths, the command line.
Every other module of lab counts (the studies, which set up scenes and starts: lab.study);
tests/harness/test_runs.py checks both lists against the package."""

SOLVER_MODULES = ("sph.solver", "sph.simulate")
"""Where every run's code closure starts: the assembled step and the driver that advances it."""


def digest(obj) -> str:
    """Short stable hash of a JSON-able object (configs via `to_mapping`), for run fingerprints."""
    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()[:16]


def _strip_docstrings(tree: ast.AST) -> ast.AST:
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant) \
                    and isinstance(body[0].value.value, str):
                node.body = body[1:] or [ast.Pass()]
    return tree


def code_digest(path) -> str:
    """Hash of a Python file's code: its syntax tree without docstrings (comments never enter it)."""
    tree = _strip_docstrings(ast.parse(Path(path).read_text(), filename=str(path)))
    return hashlib.sha256(ast.dump(tree, include_attributes=False).encode()).hexdigest()[:16]


def files_digest(files: Iterable) -> str:
    """Hash of the code of `files` (by name), each without docstrings and comments (`code_digest`)."""
    return digest({Path(f).name: code_digest(f) for f in files})


def _ours(name: str) -> bool:
    return name.split(".")[0] in PACKAGES


def _module_path(name: str) -> Optional[Path]:
    base = ROOT.joinpath(*name.split("."))
    for p in (base.with_suffix(".py"), base / "__init__.py"):
        if p.exists():
            return p
    return None


def _imports(name: str, path: Path) -> set:
    """Names of the sph modules module `name` (file `path`) imports: `import sph.x`, `from sph.x
    import y`, `from . import x`, `from .terms import y`, `from .terms.x import y`, `from sph import x`
    (a subpackage's relative imports), each resolved to the module or package it names; `from P
    import n` also counts P.n when that is a module."""
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if _ours(a.name)}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if _ours(mod):
                out.add(mod)
                out |= {f"{mod}.{a.name}" for a in node.names}  # `from . import momentum`
    return {m for m in out if _module_path(m) is not None}


def sph_closure(modules: Iterable[str]) -> list:
    """The sph modules reachable by imports from `modules` (the package `sph` itself excluded: it
    only re-exports), minus the number-neutral ones and what only they import, sorted. A package's
    `__init__` counts as a module of its own (`sph.terms` when something imports from it)."""
    todo, seen = list(modules), set()
    while todo:
        m = todo.pop()
        if m in seen or m in NUMBER_NEUTRAL:
            continue
        seen.add(m)
        todo.extend(_imports(m, _module_path(m)))
    seen -= set(PACKAGES)
    return sorted(seen)


def code_fingerprint(files: Iterable = (), modules: Iterable[str] = ()) -> str:
    """Cache key of the code behind a run: the solver's sph closure (plus `modules`, e.g. a case
    module such as "sph.cases.ldc") and the experiment's own `files` (settings, scene, run script),
    each hashed without docstrings and comments.

    Computed once per process (for a given sph root, files and modules): the key describes the code
    this process imported and runs, so editing a file while a long run goes on does not make the
    finished run look stale to the process that made it (the next process sees the edit)."""
    return _code_fingerprint(str(ROOT), tuple(str(Path(f).resolve()) for f in files), tuple(modules))


def code_modules(files: Iterable = (), modules: Iterable[str] = ()) -> list:
    """The sph modules behind a run (what `code_fingerprint` hashes besides `files`): the closure of
    the solver's modules, `modules` and the sph modules that `files` import."""
    start = set(SOLVER_MODULES) | set(modules)
    for f in files:  # the sph modules the experiment's own scripts use (its case module, ...)
        start |= _imports("__main__", Path(f))
    return sph_closure(start)


@functools.lru_cache(maxsize=None)
def _code_fingerprint(sph_root: str, files: tuple, modules: tuple) -> str:
    parts = {m: code_digest(_module_path(m)) for m in code_modules(files, modules)}
    parts.update({Path(f).name: code_digest(f) for f in files})
    return digest(parts)


def main(argv=None) -> int:
    """`python lab/keys.py FILE ...`: the files `code_fingerprint([FILE, ...])` hashes, one a
    line (the FILEs, then the sph modules), e.g. as make prerequisites. Reads no sph module (stdlib only)."""
    files = list(sys.argv[1:] if argv is None else argv)
    root = ROOT
    paths = [Path(f) for f in files] + [_module_path(m) for m in code_modules(files)]
    for p in paths:
        p = Path(p).resolve()
        print(p.relative_to(root) if p.is_relative_to(root) else p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
