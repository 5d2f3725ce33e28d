"""Cached, resumable runs of a solver into a folder, and the one run record every experiment writes.

`run_cached(spec, make_solver)` is the bookkeeping every experiment shares: skip a run whose
trajectory is complete, readable and was made from the same inputs (`spec.fingerprint`); resume one
that stopped part-way from its checkpoint; run anything else from scratch (a damaged or stale file is
kept beside it as ``traj.h5.stale-<n>``, never silently overwritten). A run folder holds

  traj.h5          trajectory in LagrangeBench's layout + checkpoint (sph.io)
  traj.xdmf        ParaView sidecar of traj.h5 (sph.xdmf)
  metadata.json    LagrangeBench metadata + the solver's settings, dt limits and timings

`record(folder, ...)` is the run record, one schema for every experiment (`RECORD_COLUMNS`, then the
run's error metrics as ``err_<name>`` columns): the accuracy-cost atlas (`make accuracy`) gathers
them. `write_table(path, rows)` rewrites a metrics table from the rows of exactly the runs of the
current config, so a removed method or a switched dtype leaves no stale row behind.

Cache keys (`code_fingerprint`): the solver's physics modules (the `sph` modules the solver imports,
transitively) and the experiment's own scripts, each parsed and hashed without docstrings and
comments. Editing a docstring, `sph/io.py`, a plot script or another experiment re-runs nothing;
editing `sph/momentum.py` re-runs every run whose solver imports it.
"""
import ast
import functools
import hashlib
import json
import resource
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterable, Optional

import numpy as np

from . import io, simulate, xdmf
from .configtools import ConfigError, digest, to_mapping

SPH_ROOT = Path(__file__).resolve().parent

NUMBER_NEUTRAL = frozenset({"sph.io", "sph.runs", "sph.xdmf", "sph.cli", "sph.animate", "sph.stamp"})
"""sph modules that cannot change a run's numbers: file formats and bookkeeping."""

SOLVER_MODULES = ("sph.solver", "sph.simulate")
"""Where every run's code closure starts: the assembled step and the driver that advances it."""

RECORD_COLUMNS = ("experiment", "target", "method", "effects", "kernel", "h_factor", "dx", "dim", "dtype", "n_particles",
                  "n_steps", "dt", "t_end", "wall_s", "compile_s", "ms_per_step", "peak_rss_mb")
"""The fixed columns of a run record; the run's error metrics follow as err_<name>."""


# -- cache keys ---------------------------------------------------------------------------------------
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


def _module_path(name: str) -> Optional[Path]:
    parts = name.split(".")[1:]
    base = SPH_ROOT.joinpath(*parts)
    for p in (base.with_suffix(".py"), base / "__init__.py"):
        if p.exists():
            return p
    return None


def _imports(name: str, path: Path) -> set:
    """Names of the sph modules module `name` (file `path`) imports."""
    pkg = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name == "sph" or a.name.startswith("sph.")}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            if mod == "sph" or mod.startswith("sph."):
                out.add(mod)
                out |= {f"{mod}.{a.name}" for a in node.names}  # `from . import momentum`
    return {m for m in out if _module_path(m) is not None}


def sph_closure(modules: Iterable[str]) -> list:
    """The sph modules reachable by imports from `modules` (the package __init__ excluded: it only
    re-exports), minus the number-neutral ones, sorted."""
    todo, seen = list(modules), set()
    while todo:
        m = todo.pop()
        if m in seen or m in NUMBER_NEUTRAL:
            continue
        seen.add(m)
        todo.extend(_imports(m, _module_path(m)))
    seen.discard("sph")
    return sorted(seen)


def code_fingerprint(files: Iterable = (), modules: Iterable[str] = ()) -> str:
    """Cache key of the code behind a run: the solver's sph closure (plus `modules`, e.g. a case
    module such as "sph.cases.ldc") and the experiment's own `files` (settings, scene, run script),
    each hashed without docstrings and comments.

    Computed once per process (for a given sph root, files and modules): the key describes the code
    this process imported and runs, so editing a file while a long run goes on does not make the
    finished run look stale to the process that made it (the next process sees the edit)."""
    return _code_fingerprint(str(SPH_ROOT), tuple(str(Path(f).resolve()) for f in files), tuple(modules))


@functools.lru_cache(maxsize=None)
def _code_fingerprint(sph_root: str, files: tuple, modules: tuple) -> str:
    files = [Path(f) for f in files]
    start = set(SOLVER_MODULES) | set(modules)
    for f in files:  # the sph modules the experiment's own scripts use (its case module, ...)
        start |= _imports("__main__", f)
    parts = {m: code_digest(_module_path(m)) for m in sph_closure(start)}
    parts.update({f.name: code_digest(f) for f in files})
    return digest(parts)


# -- frames ---------------------------------------------------------------------------------------------
def write_every_for(n_steps: int, frames: Optional[int] = None, frame_dt: Optional[float] = None,
                    dt: Optional[float] = None) -> int:
    """Steps per frame: about `frames` frames after t = 0, or one frame per `frame_dt` of time."""
    if frame_dt is not None:
        return max(1, int(round(frame_dt / dt)))
    return max(1, int(round(n_steps / frames)))


# -- the cached run ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class RunSpec:
    """What identifies one run and how to write it.

    folder       the run's folder (traj.h5, metadata.json, traj.xdmf)
    case, method names that go into metadata.json and the run record
    fingerprint  every input that can change the run's numbers (settings digest + code_fingerprint)
    t_end        simulated time; frames / frame_dt: how often to write a frame (one of them)
    keep         per-frame fields stored besides position (sph.io.FIELDS)
    metadata     experiment-specific entries of metadata.json
    u_limit      blow-up speed limit (None: the driver's default, tied to c_ref)
    """

    folder: Path
    case: str
    method: str
    fingerprint: str
    t_end: float
    frames: Optional[int] = None
    frame_dt: Optional[float] = None
    keep: tuple = io.DEFAULT_KEEP
    connectivity_radius_factor: float = 1.45
    metadata: dict = field(default_factory=dict)
    u_limit: Optional[float] = None

    def __post_init__(self):
        if (self.frames is None) == (self.frame_dt is None):
            raise ValueError("RunSpec: give exactly one of frames and frame_dt")

    @property
    def traj(self) -> Path:
        return Path(self.folder) / "traj.h5"

    @property
    def meta_path(self) -> Path:
        return Path(self.folder) / "metadata.json"

    @property
    def label(self) -> str:
        return Path(self.folder).name


@dataclass(frozen=True)
class RunOutcome:
    """status: "skipped" (complete and current), "resumed" or "run"; result: the driver's RunResult
    (None when skipped)."""

    status: str
    folder: Path
    result: Optional[simulate.RunResult] = None


def read_metadata(path) -> Optional[dict]:
    """metadata.json as a dict, or None when it is missing or not valid JSON."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def stored_state(spec: RunSpec) -> str:
    """"current" (complete, readable, same inputs, every frame present), "partial" (same inputs,
    resumable from its checkpoint), "absent", "stale" (other inputs) or "damaged" (unreadable)."""
    if not spec.traj.exists():
        return "absent"
    status = io.trajectory_status(spec.traj)
    if not status["exists"]:
        return "damaged"
    if status["fingerprint"] != spec.fingerprint:
        return "stale"
    meta = read_metadata(spec.meta_path)
    if status["complete"]:
        if meta is not None and meta.get("fingerprint") == spec.fingerprint \
                and status["n_frames"] == meta.get("sequence_length"):
            return "current"
        return "damaged"
    return "partial" if status["checkpoint_step"] is not None else "damaged"


def _set_aside(path: Path, why: str) -> None:
    n = 0
    while path.with_name(f"{path.name}.stale-{n}").exists():
        n += 1
    target = path.with_name(f"{path.name}.stale-{n}")
    path.replace(target)
    print(f"{path}: {why}; kept as {target.name}, running from scratch", flush=True)


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far, MB (Linux reports ru_maxrss in kB)."""
    kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return kb / 1024.0 if sys.platform != "darwin" else kb / 2**20


def _metadata(spec: RunSpec, solver, n_total: int, write_every: int, **extra) -> dict:
    sc = solver.scene
    return io.lagrangebench_metadata(
        case=spec.case, solver=spec.method, dim=sc.dim, dx=sc.dx, dt=solver.dt, t_end=n_total * solver.dt,
        sequence_length=1 + -(-n_total // write_every), write_every=write_every, num_particles_max=sc.n,
        periodic_boundary_conditions=sc.domain.periodic, bounds=[(0.0, b) for b in sc.domain.box],
        default_connectivity_radius=spec.connectivity_radius_factor * sc.dx, dtype=solver.numerics.dtype,
        effects=sc.effects.names(), kernel=solver.numerics.kernel, n_fluid=int(sc.fluid_mask.sum()),
        material=to_mapping(sc.material), numerics=to_mapping(solver.numerics), dt_limits=solver.dt_limits,
        kept_fields=list(spec.keep), fingerprint=spec.fingerprint, **spec.metadata, **extra)


def run_cached(spec: RunSpec, make_solver: Callable, initial_state: Optional[Callable] = None,
               progress: bool = True, callback: Optional[Callable] = None) -> RunOutcome:
    """Run, resume or skip one run (see the module docstring).

    make_solver()            -> sph.Solver (called only when something has to run)
    initial_state(solver)    -> (state, nbrs) of a fresh run (default: solver.init_fn())
    callback(step, t, state) after every frame, as in sph.simulate.run
    """
    kind = stored_state(spec)
    label = spec.label
    if kind == "current":
        print(f"{label}: complete, skipped", flush=True)
        return RunOutcome("skipped", Path(spec.folder))
    if kind in ("stale", "damaged"):
        _set_aside(spec.traj, "made from other inputs" if kind == "stale" else "damaged or incomplete")
    solver = make_solver()
    n_steps = solver.n_steps(spec.t_end)
    write_every = write_every_for(n_steps, spec.frames, spec.frame_dt, solver.dt)
    resume = kind == "partial"
    if resume:
        writer = io.TrajectoryWriter.open(spec.traj)
    else:
        writer = io.TrajectoryWriter.create(spec.traj, solver.scene.tag, solver.scene.dim, dtype=solver.dtype,
                                            keep=spec.keep, attrs={"fingerprint": spec.fingerprint})
    with writer:
        if resume:
            state, nbrs, step0 = simulate.resume(solver, writer)
            print(f"{label}: resuming at step {step0} of {n_steps}", flush=True)
        else:
            state, nbrs = initial_state(solver) if initial_state is not None else solver.init_fn()
            step0 = 0
            print(f"{label}: {solver.scene.n} particles ({int(solver.scene.fluid_mask.sum())} fluid), "
                  f"dt {solver.dt:.4g}, {n_steps} steps, a frame every {write_every}", flush=True)
        if not resume or read_metadata(spec.meta_path) is None:
            io.write_metadata(spec.meta_path, _metadata(spec, solver, n_steps, write_every))
        res = simulate.run(solver, state, nbrs, spec.t_end, write_every, writer=writer, progress=progress,
                           step0=step0, desc=label, callback=callback, u_limit=spec.u_limit)
        timings = {"wall_s": res.wall_s_total, "compile_s": res.compile_s, "n_steps": res.step_end,
                   "n_reallocations": res.n_reallocations_total, "peak_rss_mb": peak_rss_mb()}
        position = writer.group["position"][...]
        stats = io.lagrangebench_stats(position, solver.scene.domain.box, solver.scene.domain.periodic)
        io.write_metadata(spec.meta_path, _metadata(spec, solver, n_steps, write_every, **stats, **timings))
        writer.mark_complete(**timings)  # last: a run is complete only once its metadata is written
    xdmf.write_sidecar(spec.traj)
    print(f"{label}: {res.n_steps} steps of {solver.scene.n} particles in {res.wall_s:.2f} s "
          f"({res.ms_per_step:.2f} ms/step), compile {res.compile_s:.2f} s", flush=True)
    return RunOutcome("resumed" if resume else "run", Path(spec.folder), res)


def select(option: str, given: Optional[list], allowed: list) -> Optional[list]:
    """A command-line subset (`--only`, `--dx`) of the config's own values, or None for all of
    them. A value the config does not have is an error naming the option: the config, validated
    on load, is the only place that defines runs (`--dx 0.03` cannot bypass its rules)."""
    if given is None:
        return None
    out = []
    for g in given:
        match = [a for a in allowed if (np.isclose(a, g, rtol=1e-9, atol=0) if isinstance(a, float) else a == g)]
        if not match:
            raise ConfigError(f"{option} {g!r}: not one of this profile's values {list(allowed)}; "
                              "add it to the profile in config.yaml (where it is validated) to run it")
        out.append(match[0])
    return out


# -- the run record -----------------------------------------------------------------------------------
def record(folder, *, experiment: str, target: str, method: str, errors: dict, **extra) -> dict:
    """The run record of a finished run in `folder` (from its metadata.json and traj.h5 attrs):
    RECORD_COLUMNS, then `errors` as err_<name>, then `extra` columns."""
    folder = Path(folder)
    meta = read_metadata(folder / "metadata.json")
    if meta is None:
        raise FileNotFoundError(f"{folder / 'metadata.json'}: missing or damaged; re-run the experiment")
    n_steps = int(meta.get("n_steps", 0))
    wall = float(meta.get("wall_s", np.nan))
    rec = {"experiment": experiment, "target": target, "method": method,
           "effects": "+".join(meta.get("effects", [])) or "standard", "kernel": meta.get("kernel", ""),
           "h_factor": float((meta.get("numerics") or {}).get("h_factor", np.nan)), "dx": float(meta["dx"]), "dim": int(meta["dim"]), "dtype": meta["dtype"],
           "n_particles": int(meta["num_particles_max"]), "n_steps": n_steps, "dt": float(meta["dt"]),
           "t_end": float(meta["t_end"]), "wall_s": wall, "compile_s": float(meta.get("compile_s", np.nan)),
           "ms_per_step": 1e3 * wall / n_steps if n_steps else np.nan,
           "peak_rss_mb": float(meta.get("peak_rss_mb", np.nan))}
    rec.update({f"err_{k}": float(v) for k, v in errors.items()})
    rec.update(extra)
    return rec


def cached_row(folder, key: str, compute: Callable) -> dict:
    """A run's metrics row, recomputed by `compute()` only when `key` (a digest of the trajectory's
    fingerprint, the analysis settings and code) differs from the one stored in metrics_row.json."""
    path = Path(folder) / "metrics_row.json"
    stored = read_metadata(path)
    if stored is not None and stored.get("key") == key:
        return stored["row"]
    row = compute()
    io.write_metadata(path, {"key": key, "row": row})
    return row


def cached_positions(path, fingerprint: str, compute: Callable, label: str, **meta) -> np.ndarray:
    """Initial positions (e.g. a relaxation, sph.relax) cached in `path` (.npy) with a .json sidecar:
    reused when the sidecar holds `fingerprint`, else `compute()` -> (r, info) runs and both files are
    written (the array atomically; `meta` and `info` go into the sidecar). Prints one summary line."""
    path = Path(path)
    side = path.with_suffix(".json")
    stored = read_metadata(side) if path.exists() else None
    if stored is not None and stored.get("fingerprint") == fingerprint:
        try:
            return np.load(path)
        except (ValueError, OSError):
            pass  # damaged: computed again below
    r, info = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.npy")
    np.save(tmp, r)
    tmp.replace(path)
    io.write_metadata(side, {"fingerprint": fingerprint, **meta, **info})
    nan = float("nan")
    print(f"{label}: {info.get('steps')} steps, max |rho/rho_ref - 1| {info.get('density_error_start', nan):.3g} -> "
          f"{info.get('density_error_end', nan):.3g}, u_max {info.get('u_max_end', nan):.3g}", flush=True)
    return r


def save_record(folder, rec: dict) -> None:
    """Write the run record as record.json in the run folder (what `make accuracy` gathers)."""
    io.write_metadata(Path(folder) / "record.json", rec)


def write_table(path, rows: list, sort: Optional[list] = None, ascending=True):
    """Rewrite the csv table `path` from `rows` (atomically). Returns the DataFrame. With no rows
    (no run of the current config has finished) the table is removed: an old one would list runs
    that are not the config's, and a csv without columns cannot be read back."""
    import pandas as pd

    df = pd.DataFrame(rows)
    path = Path(path)
    if df.empty:
        path.unlink(missing_ok=True)
        return df
    if sort:
        df = df.sort_values(sort, ascending=ascending, ignore_index=True)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    df.to_csv(tmp, index=False)
    tmp.replace(path)
    return df


def read_table(path):
    """A metrics csv written by `write_table`, with an error naming the file when it is damaged."""
    import pandas as pd

    if not Path(path).exists():
        raise FileNotFoundError(f"{path}: no metrics table (no run of the current config has finished); run its "
                                "experiment first")
    try:
        return pd.read_csv(path)
    except Exception as e:  # pandas raises several types for empty, binary or malformed files
        raise RuntimeError(f"{path}: damaged metrics table ({type(e).__name__}: {e}); re-run its experiment "
                           "(make rebuilds it from the trajectories)") from None
