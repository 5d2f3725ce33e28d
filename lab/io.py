"""Trajectory files in the LagrangeBench layout, with a resumable checkpoint, and `metadata.json`.

One HDF5 file holds one group per trajectory ("00000", "00001", ...). A trajectory group holds

  position       (T, N, dim)  particle positions per frame          (what LagrangeBench reads)
  particle_type  (N,)         particle tag (0 = fluid, as in LagrangeBench)
  velocity       (T, N, dim)  transport velocity v (the particles' }
                              own velocity; = u without TVF)         } kept fields, optional
  momentum_velocity (T, N, dim) momentum velocity u                  }
  density        (T, N)       density                                }
  pressure       (T, N)       pressure                               }
  temperature    (T, N)       temperature (scenes that declare heat) }
  time, step     (T,)         simulated time and step number of each frame
  u_max, e_kin, density_error (T,)  frame diagnostics (sph.diagnostics)
  checkpoint/                 every field of the last written ParticleState (attrs: step, t, ...)

Frames are appended one at a time into resizable datasets and the file is flushed after each frame
and checkpoint, so a run that dies keeps everything up to its last frame and can resume from the
checkpoint (`TrajectoryWriter.open` + `load_checkpoint`). The group attribute `complete` marks a
finished run; `fingerprint` (any string the caller chooses) identifies what was run, so a caller can
tell a finished run of the same inputs from a stale one.
"""
import json
from pathlib import Path
from typing import Optional, Sequence

import h5py
import jax.numpy as jnp
import numpy as np

from sph.simulate import SERIES  # noqa: F401  (the per-frame series the driver records)
from sph.state import ParticleState
from .deliver import note_input

FIELDS = {"position": "r", "velocity": "v", "momentum_velocity": "u", "density": "rho", "pressure": "p",
          "temperature": "T"}
"""Per-particle trajectory datasets and the ParticleState field each one stores."""

DEFAULT_KEEP = ("velocity", "density", "pressure")


class OutputError(OSError, RuntimeError):
    """A result file is missing, damaged or incomplete; the message names the file and what to do
    (`lab.cli.main_guard` prints it as one line)."""


class MissingOutput(FileNotFoundError, OutputError):
    """A result file that an earlier step writes is not there (yet)."""


class TrajectoryWriter:
    """Append frames of one trajectory to an HDF5 file and keep a checkpoint of the last state.

    Use `create` for a new file (overwrites) or `open` to continue an existing one; both return a
    context manager that closes the file.
    """

    def __init__(self, file: h5py.File, traj: str):
        self.file = file
        self.path = Path(file.filename)
        self.traj = traj
        self.group = file[traj]

    # -- construction -------------------------------------------------------------------------------
    @classmethod
    def create(cls, path, particle_type, dim: int, dtype=np.float64, keep: Sequence[str] = DEFAULT_KEEP,
               traj: str = "00000", attrs: Optional[dict] = None) -> "TrajectoryWriter":
        """New file at `path` (parents created, an old file replaced) with an empty trajectory.
        `keep`: which of velocity/momentum_velocity/density/pressure/temperature to store besides
        position; `attrs`: group attrs."""
        unknown = [k for k in keep if k not in FIELDS or k == "position"]
        if unknown:
            raise ValueError(f"keep: {unknown[0]!r} is not one of {sorted(set(FIELDS) - {'position'})}")
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        f = h5py.File(path, "w")
        g = f.create_group(traj)
        ptype = np.asarray(particle_type, np.int32)
        n = ptype.shape[0]
        g.create_dataset("particle_type", data=ptype)
        for name in ("position", *keep):
            shape = (n, dim) if name in ("position", "velocity", "momentum_velocity") else (n,)
            g.create_dataset(name, shape=(0, *shape), maxshape=(None, *shape), chunks=(1, *shape), dtype=dtype)
        for name in SERIES:
            g.create_dataset(name, shape=(0,), maxshape=(None,), chunks=(256,),
                             dtype=np.int64 if name == "step" else np.float64)
        g.attrs["complete"] = False
        for k, v in (attrs or {}).items():
            g.attrs[k] = v
        f.flush()
        return cls(f, traj)

    @classmethod
    def open(cls, path, traj: str = "00000") -> "TrajectoryWriter":
        """Continue an existing trajectory. Frames written after the checkpoint (a crash between the
        frame and the checkpoint) are dropped so that frames and checkpoint agree."""
        f = h5py.File(path, "a")
        if traj not in f:
            f.close()
            raise KeyError(f"{path}: no trajectory group {traj!r}")
        w = cls(f, traj)
        if "checkpoint" in w.group:
            last = int(w.group["checkpoint"].attrs["step"])
            steps = w.group["step"][...]
            w._truncate(int(np.searchsorted(steps, last, side="right")))
        return w

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        if self.file.id.valid:
            self.file.close()

    # -- frames -------------------------------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        return self.group["position"].shape[0]

    @property
    def kept(self) -> list:
        return [k for k in FIELDS if k in self.group]

    def append(self, state: ParticleState, step: int, t: float, diag: Optional[dict] = None):
        """Append one frame: kept per-particle fields of `state`, time, step and diagnostics."""
        i = self.n_frames
        for name in self.kept:
            value = getattr(state, FIELDS[name])
            if value is None:
                raise ValueError(f"{self.path}: keeps {name!r}, but the state has no {FIELDS[name]} "
                                 f"(its scene does not declare the effect that makes it)")
            ds = self.group[name]
            ds.resize(i + 1, axis=0)
            ds[i] = np.asarray(value)
        diag = diag or {}
        values = {"time": t, "step": step, **{k: diag.get(k, np.nan) for k in SERIES[2:]}}
        for name in SERIES:
            ds = self.group[name]
            ds.resize(i + 1, axis=0)
            ds[i] = values[name]
        self.file.flush()

    def frames(self) -> dict:
        """The per-frame scalar series as numpy arrays (time, step, u_max, e_kin, density_error)."""
        return {name: self.group[name][...] for name in SERIES}

    def _truncate(self, n: int):
        for name in (*self.kept, *SERIES):
            ds = self.group[name]
            if ds.shape[0] > n:
                ds.resize(n, axis=0)
        self.file.flush()

    # -- checkpoint ---------------------------------------------------------------------------------
    def save_checkpoint(self, state: ParticleState, step: int, t: float, **attrs):
        """Overwrite the checkpoint with every field of `state` plus `step`, `t` and `attrs`."""
        g = self.group.require_group("checkpoint")
        names = state.field_names()
        for name in list(g.keys()):
            if name not in names:
                del g[name]
        for name in names:
            a = np.asarray(getattr(state, name))
            if name in g and g[name].shape == a.shape and g[name].dtype == a.dtype:
                g[name][...] = a
            else:
                if name in g:
                    del g[name]
                g.create_dataset(name, data=a)
        g.attrs["step"] = int(step)
        g.attrs["t"] = float(t)
        g.attrs["n_frames"] = self.n_frames
        for k, v in attrs.items():
            g.attrs[k] = v
        self.file.flush()

    def has_checkpoint(self) -> bool:
        return "checkpoint" in self.group

    def load_checkpoint(self):
        """(ParticleState, step, attrs) from the checkpoint."""
        return _read_checkpoint(self.group)

    # -- completion ---------------------------------------------------------------------------------
    def mark_complete(self, **attrs):
        for k, v in attrs.items():
            self.group.attrs[k] = v
        self.group.attrs["complete"] = True
        self.file.flush()


def _read_checkpoint(group):
    if "checkpoint" not in group:
        raise KeyError(f"{group.file.filename}: trajectory {group.name} has no checkpoint")
    g = group["checkpoint"]
    fields = {name: jnp.asarray(g[name][...]) for name in g.keys()}
    state = ParticleState(**fields)
    return state, int(g.attrs["step"]), dict(g.attrs)


def load_checkpoint(path, traj: str = "00000"):
    """(ParticleState, step, attrs) from the checkpoint of trajectory `traj` in `path`."""
    with h5py.File(path, "r") as f:
        return _read_checkpoint(f[traj])


def read_trajectory(path, traj: str = "00000") -> dict:
    """Every dataset of a trajectory (checkpoint excluded) as numpy arrays, plus its attrs under
    'attrs'."""
    note_input(path)  # a deliverable made from it is re-made when it changes (lab.deliver)
    try:
        with h5py.File(path, "r") as f:
            g = f[traj]
            out = {k: g[k][...] for k in g.keys() if isinstance(g[k], h5py.Dataset)}
            out["attrs"] = dict(g.attrs)
    except (OSError, KeyError, ValueError, TypeError) as e:
        raise OutputError(f"{path}: cannot read trajectory {traj} ({e}); the file is damaged or incomplete: "
                      "re-run its experiment (its run script, which make calls, sets it aside and redoes the run)") from None
    return out


def trajectory_status(path, traj: str = "00000") -> dict:
    """{'exists', 'complete', 'fingerprint', 'n_frames', 'checkpoint_step'} without raising; a file
    that cannot be read counts as absent."""
    out = {"exists": False, "complete": False, "fingerprint": None, "n_frames": 0, "checkpoint_step": None}
    try:
        with h5py.File(path, "r") as f:
            g = f[traj]
            out.update(exists=True, complete=bool(g.attrs.get("complete", False)),
                       fingerprint=g.attrs.get("fingerprint"), n_frames=g["position"].shape[0])
            if "checkpoint" in g:
                out["checkpoint_step"] = int(g["checkpoint"].attrs["step"])
    except (OSError, KeyError):
        pass
    return out


# -- metadata.json ----------------------------------------------------------------------------------
def lagrangebench_stats(position, box, periodic) -> dict:
    """vel/acc mean and std per dimension as LagrangeBench normalizes them: velocity is the
    (minimum-image) displacement between consecutive frames, acceleration its difference."""
    pos = np.asarray(position, dtype=np.float64)
    if pos.shape[0] < 3:
        return {}
    box = np.asarray(box, dtype=np.float64)
    vel = np.diff(pos, axis=0)
    per = np.asarray(periodic, bool)
    vel = np.where(per, vel - box * np.round(vel / box), vel)
    acc = np.diff(vel, axis=0)
    dim = pos.shape[-1]
    v, a = vel.reshape(-1, dim), acc.reshape(-1, dim)
    return {"vel_mean": v.mean(0).tolist(), "vel_std": v.std(0).tolist(),
            "acc_mean": a.mean(0).tolist(), "acc_std": a.std(0).tolist()}


def lagrangebench_metadata(*, case: str, solver: str, dim: int, dx: float, dt: float, t_end: float,
                           sequence_length: int, write_every: int, num_particles_max: int,
                           periodic_boundary_conditions, bounds, default_connectivity_radius: float,
                           dtype: str, **extra) -> dict:
    """The metadata.json mapping: LagrangeBench's keys first, then anything in `extra`."""
    meta = {
        "case": case, "solver": solver, "dim": int(dim), "dx": float(dx), "dt": float(dt),
        "t_end": float(t_end), "sequence_length": int(sequence_length), "write_every": int(write_every),
        "num_particles_max": int(num_particles_max),
        "periodic_boundary_conditions": [bool(p) for p in periodic_boundary_conditions],
        "bounds": [[float(lo), float(hi)] for lo, hi in bounds],
        "default_connectivity_radius": float(default_connectivity_radius), "dtype": str(dtype),
    }
    meta.update(extra)
    return meta


def read_metadata(path) -> Optional[dict]:
    """metadata.json as a dict, or None when it is missing or not valid JSON."""
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def write_metadata(path, metadata: dict):
    """Write `metadata` as indented JSON (atomically: temp file, then rename)."""
    from .atomic import write_text

    write_text(path, json.dumps(metadata, indent=2, default=_json_default) + "\n")


def _json_default(x):
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, (np.ndarray, tuple)):
        return list(x)
    raise TypeError(f"not JSON serializable: {x!r}")
