"""The cached run: a solver run into a folder, skipped when it is complete and current, resumed
when it stopped part-way.

`run_cached(spec, make_solver)` is the bookkeeping every experiment shares: skip a run whose
trajectory is complete, readable and was made from the same inputs (`spec.fingerprint`, see
`lab.keys`); resume one that stopped part-way from its checkpoint; run anything else from
scratch (a damaged or stale file is kept beside it as ``traj.h5.stale-<n>``, never silently
overwritten). A run folder holds

  traj.h5          trajectory in LagrangeBench's layout + checkpoint (lab.io)
  traj.xdmf        ParaView sidecar of traj.h5 (lab.xdmf)
  metadata.json    LagrangeBench metadata + the solver's settings, dt limits and timings

`cached_positions` and `cached_row` cache smaller results the same way (relaxed start positions, a
run's metrics row). The run record and the metrics tables are `lab.record` and
`lab.tables`.
"""
import resource
import shutil
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

import jax
import numpy as np

from sph import simulate
from . import io, xdmf
from .lock import folder_lock
from .other_load import OtherLoad
from .configtools import to_mapping
from .io import read_metadata
from .stamp import note_current


def write_every_for(n_steps: int, frames: Optional[int] = None, frame_dt: Optional[float] = None,
                    dt: Optional[float] = None) -> int:
    """Steps per frame: about `frames` frames after t = 0, or one frame per `frame_dt` of time."""
    if frame_dt is not None:
        return max(1, int(round(frame_dt / dt)))
    return max(1, int(round(n_steps / frames)))


@dataclass(frozen=True)
class RunSpec:
    """What identifies one run and how to write it.

    folder       the run's folder (traj.h5, metadata.json, traj.xdmf)
    case, method names that go into metadata.json and the run record
    fingerprint  every input that can change the run's numbers (settings digest + code_fingerprint)
    t_end        simulated time; frames / frame_dt: how often to write a frame (one of them)
    keep         per-frame fields stored besides position (lab.io.FIELDS)
    metadata     experiment-specific entries of metadata.json
    u_limit      blow-up speed limit (None: the driver's default, tied to c_ref)
    devices      how many devices the steps run on (sph.parallel; not part of the fingerprint: the
                 numbers equal one device's to round-off, so a run made on D devices is current for
                 any D, and its metadata.json and record say which it was made on)
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
    devices: int = 1

    def __post_init__(self):
        if (self.frames is None) == (self.frame_dt is None):
            raise ValueError("RunSpec: give exactly one of frames and frame_dt")
        if not (isinstance(self.devices, int) and not isinstance(self.devices, bool) and self.devices >= 1):
            raise ValueError(f"RunSpec: devices must be a whole number >= 1, got {self.devices!r}")

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


def check_fits(where: str, n: int, dim: int, dx: float, numerics) -> int:
    """Refuse, from the config alone (no scene, no array, no relaxation built), a run of `n` particles
    at spacing `dx` with `numerics` that cannot fit into the available memory: the same estimate as
    `sph.build_solver`'s (sph.memory.check_memory, neighbour_slots), made before a study builds or
    relaxes anything, so a resolution that does not fit is refused in seconds. Returns the bytes."""
    from sph.memory import check_memory, neighbour_slots
    from sph.kernels import make_kernel

    cutoff = make_kernel(numerics.kernel, numerics.h_factor * dx, dim).cutoff
    slots = neighbour_slots(cutoff, numerics.skin_factor * dx, dx, dim, numerics.capacity_multiplier)
    return check_memory(int(n), dim, slots, np.dtype(numerics.dtype).itemsize, where, dx)


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


KEEP_STALE = 3
"""How many set-aside copies (``<file>.stale-<n>``) of one file are kept: the newest ones."""


def set_aside(path: Path, why: str, then: str = "running from scratch") -> None:
    """Rename `path` to the next ``<name>.stale-<n>`` and say so in one line; of its set-aside copies
    only the newest KEEP_STALE stay (flipping a setting back and forth does not pile them up)."""
    target, dropped = _move_aside(path)
    extra = f"; removed older copies {', '.join(p.name for p in dropped)}" if dropped else ""
    print(f"{path}: {why}; kept as {target.name}{extra}, {then}", flush=True)


def _move_aside(path: Path):
    """Rename `path` to the next ``<name>.stale-<n>``, drop the copies beyond the newest KEEP_STALE;
    (the new copy, the removed ones)."""
    olds = sorted(_stale_copies(path), key=lambda p: p[0])
    n = olds[-1][0] + 1 if olds else 0
    target = path.with_name(f"{path.name}.stale-{n}")
    path.replace(target)
    dropped = [p for _, p in olds[:max(0, len(olds) + 1 - KEEP_STALE)]]
    for p in dropped:
        shutil.rmtree(p) if p.is_dir() else p.unlink(missing_ok=True)
    return target, dropped


def _stale_copies(path: Path) -> list:
    """(n, path) of every ``<name>.stale-<n>`` beside `path`."""
    out = []
    for p in path.parent.glob(f"{path.name}.stale-*"):
        tail = p.name[len(path.name) + len(".stale-"):]
        if tail.isdigit():
            out.append((int(tail), p))
    return out


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

    The run folder is locked while this runs (lab.lock): a second process asking for the same
    run (`make -j2`) waits, then finds it complete and skips it.
    """
    with folder_lock(spec.folder):
        return _run_locked(spec, make_solver, initial_state, progress, callback)


def _run_locked(spec: RunSpec, make_solver: Callable, initial_state: Optional[Callable], progress: bool,
                callback: Optional[Callable]) -> RunOutcome:
    kind = stored_state(spec)
    label = spec.label
    if kind == "current":
        note_current(spec.folder)
        print(f"{label}: complete, skipped", flush=True)
        return RunOutcome("skipped", Path(spec.folder))
    if kind in ("stale", "damaged"):
        set_aside(spec.traj, "made from other inputs" if kind == "stale" else "damaged or incomplete")
    solver = make_solver()
    n_steps = solver.n_steps(spec.t_end)
    write_every = write_every_for(n_steps, spec.frames, spec.frame_dt, solver.dt)
    resumed = _open_checkpoint(spec, solver) if kind == "partial" else None
    resume = resumed is not None
    if resume:
        writer, (state, nbrs, step0) = resumed
    else:
        writer = io.TrajectoryWriter.create(spec.traj, solver.scene.tag, solver.scene.dim, dtype=solver.dtype,
                                            keep=spec.keep, attrs={"fingerprint": spec.fingerprint})
    with writer:
        if resume:
            print(f"{label}: resuming at step {step0} of {n_steps}", flush=True)
        else:
            state, nbrs = initial_state(solver) if initial_state is not None else solver.init_fn()
            step0 = 0
            print(f"{label}: {solver.scene.n} particles ({int(solver.scene.fluid_mask.sum())} fluid), "
                  f"dt {solver.dt:.4g}, {n_steps} steps, a frame every {write_every}", flush=True)
        if not resume or read_metadata(spec.meta_path) is None:
            io.write_metadata(spec.meta_path, _metadata(spec, solver, n_steps, write_every))
        with OtherLoad() as load:
            res = simulate.run(solver, state, nbrs, spec.t_end, write_every, writer=writer, progress=progress,
                               step0=step0, desc=label, callback=callback, u_limit=spec.u_limit,
                               devices=spec.devices)
        timings = {"wall_s": res.wall_s_total, "compile_s": res.compile_s, "n_steps": res.step_end,
                   "n_reallocations": res.n_reallocations_total, "peak_rss_mb": peak_rss_mb(),
                   "devices": spec.devices, "processes": jax.process_count()}
        position = writer.group["position"][...]
        stats = io.lagrangebench_stats(position, solver.scene.domain.box, solver.scene.domain.periodic)
        layout = {"decomposition": res.decomposition} if res.decomposition is not None else {}
        io.write_metadata(spec.meta_path, _metadata(spec, solver, n_steps, write_every, **stats, **timings,
                                                      **layout, **load.fields()))
        writer.mark_complete(**timings, other_load=load.cores)  # last: a run is complete only once its metadata is written
    xdmf.write_sidecar(spec.traj)
    note_current(spec.folder)
    print(f"{label}: {res.n_steps} steps of {solver.scene.n} particles in {res.wall_s:.2f} s "
          f"({res.ms_per_step:.2f} ms/step), compile {res.compile_s:.2f} s", flush=True)
    return RunOutcome("resumed" if resume else "run", Path(spec.folder), res)


def _open_checkpoint(spec: RunSpec, solver):
    """(writer, (state, nbrs, step)) of a run that stopped part-way, or None when its checkpoint cannot
    be read or does not fit the solver (then the file is set aside, naming it, and the run starts over)."""
    writer = None
    try:
        writer = io.TrajectoryWriter.open(spec.traj)
        state, nbrs, step0 = simulate.resume(solver, writer)
        if state.r.shape != (solver.scene.n, solver.scene.dim):
            raise ValueError(f"checkpoint holds {state.r.shape[0]} particles, the scene {solver.scene.n}")
        return writer, (state, nbrs, step0)
    except (OSError, KeyError, ValueError, TypeError, AttributeError) as e:
        if writer is not None:
            writer.close()
        set_aside(spec.traj, f"damaged checkpoint ({' '.join(str(e).split())[:160]})")
        return None


def require_current(spec: RunSpec, remedy: str) -> None:
    """Refuse (io.MissingOutput, one line naming the run, its state and `remedy`) to derive anything
    from a run that is not the current config's: a metrics row cached under the config's key but
    computed from a trajectory of other inputs would outlive every later make."""
    state = stored_state(spec)
    if state != "current":
        what = {"absent": "has not been run", "stale": "was made from other inputs (the config or code changed)",
                "partial": "stopped part-way", "damaged": "is damaged or incomplete"}[state]
        raise io.MissingOutput(f"{spec.traj}: run {spec.label} {what}; {remedy}")


def cached_row(folder, key: str, compute: Callable) -> dict:
    """A run's metrics row, recomputed by `compute()` only when `key` (a digest of the trajectory's
    fingerprint, the analysis settings and code) differs from the one stored in metrics_row.json."""
    path = Path(folder) / "metrics_row.json"
    stored = read_metadata(path)
    note_current(path)
    if stored is not None and stored.get("key") == key and isinstance(stored.get("row"), dict):
        return stored["row"]
    row = compute()
    io.write_metadata(path, {"key": key, "row": row})
    return row


def cached_positions(path, fingerprint: str, compute: Callable, label: str, **meta) -> np.ndarray:
    """Initial positions (e.g. a relaxation, sph.relax) cached in `path` (.npy) with a .json sidecar
    that says what they were made for: the config and code (`fingerprint`), `meta` (e.g. dx, n_side,
    relaxation) and the array's shape (particle count, dimension). Reused only when all of these
    match and the array is readable and finite; a cache made for something else, or damaged, is set
    aside (``.stale-<n>``) with one line naming the file and what differs, and `compute()` -> (r, info)
    runs again; both files are then written (the array atomically; `meta` and `info` go into the
    sidecar). Prints one summary line."""
    path = Path(path)
    with folder_lock(path.parent, name=f".{path.stem}.lock"):  # one writer at a time (make -j2)
        return _positions_locked(path, fingerprint, compute, label, **meta)


def _cache_mismatch(path: Path, side: Path, fingerprint: str, meta: dict):
    """(positions, None) when the cache at `path` was made for these inputs, else (None, what differs)
    (None, None) when there is no cache."""
    if not path.exists():
        return None, None
    stored = read_metadata(side)
    if stored is None:
        return None, f"its sidecar {side.name} is missing or damaged"
    for k, v in meta.items():
        if k in stored and _plain(stored[k]) != _plain(v):
            return None, f"made for {k} = {stored[k]!r}, not {v!r}"
    if stored.get("fingerprint") != fingerprint:
        return None, "made from another config or code"
    try:
        r = np.load(path)
    except (ValueError, OSError, EOFError) as e:
        return None, f"unreadable ({' '.join(str(e).split())[:120]})"
    shape = stored.get("shape")
    if shape is not None and list(r.shape) != list(shape):
        return None, f"holds {r.shape[0]} particles of dimension {r.shape[-1]}, made for {shape[0]} of dimension {shape[-1]}"
    if not np.all(np.isfinite(r)):
        return None, "holds non-finite positions"
    return r, None


def _plain(v):
    """A value as JSON would store it (tuples as lists, numpy scalars as Python ones)."""
    import json

    return json.loads(json.dumps(v, default=io._json_default))


def _positions_locked(path: Path, fingerprint: str, compute: Callable, label: str, **meta) -> np.ndarray:
    side = path.with_suffix(".json")
    r, why = _cache_mismatch(path, side, fingerprint, meta)
    if r is not None:
        return r
    if why is not None:
        set_aside(path, f"cached start {why}", then="computing it again")
        if side.exists():
            _move_aside(side)
    r, info = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.stem + ".tmp.npy")
    np.save(tmp, r)
    tmp.replace(path)
    io.write_metadata(side, {"fingerprint": fingerprint, **meta, "shape": list(np.shape(r)), **info})
    nan = float("nan")
    print(f"{label}: {info.get('steps')} steps, max |rho/rho_ref - 1| {info.get('density_error_start', nan):.3g} -> "
          f"{info.get('density_error_end', nan):.3g}, u_max {info.get('u_max_end', nan):.3g}", flush=True)
    return r
