"""The 2D Taylor-Green study (JAX-SPH Figs. 4-5): every (dx, method) of a profile, each method's
effects on the analytical TGV velocity over the relaxed particles of its spacing (sph.cases.tgv; the
protocol is lab.experiment's). The accuracy atlas's TGV sweep runs this study too, with overrides.

Per run (`<method>_dx<dx>`), against the analytical decay (sph.cases.tgv):
  u_max_relerr_t<t>, e_kin_relerr_t<t>   |sim / exact - 1| at each `eval_times` entry (interpolated
                                          between frames; NaN beyond t_end)
  u_max_relerr_mean, e_kin_relerr_mean   their time averages (trapezoidal over all frames)
  density_error_max                      the largest max |rho / rho_ref - 1| of any frame
with the run's size and cost (n_particles, n_steps, dt, wall_s, compile_s, ms_per_step, ...).
"""
import dataclasses
from dataclasses import dataclass, field

import numpy as np

from sph.cases import tgv
from sph.config import Effects, Material, Numerics
from sph.errors import require, require_finite
from sph.lattice import count
from sph.relax import Relaxation
from lab.protocol import Start, Table
from lab.layout import dx_tag
from lab.runs import check_fits
from lab.study import Method, check_methods, check_output

TARGET = "fig5"
TABLE = Table(rows="metrics", sort=("dx", "method"), ascending=(False, True))


@dataclass(frozen=True)
class Settings:
    """One profile of config.yaml (see its comments for each key)."""

    methods: tuple[Method, ...]
    dx: tuple[float, ...]
    t_end: float
    case: str = "tgv2d"
    material: Material = field(default_factory=Material)
    numerics: Numerics = field(default_factory=Numerics)
    frames: int = 200
    eval_times: tuple[float, ...] = (0.5, 1.0, 2.0)
    keep: tuple[str, ...] = ("velocity", "density", "pressure")
    connectivity_radius_factor: float = 1.45
    relaxation: Relaxation = field(default_factory=Relaxation)
    fig4_method: str = "tvf"

    def __post_init__(self):
        require_finite(self)
        names = check_methods(self.methods)
        require(len(self.dx) > 0, "dx", "needs at least one particle spacing")
        for i, dx in enumerate(self.dx):
            require(dx > 0 and abs(1.0 / dx - round(1.0 / dx)) < 1e-6, f"dx[{i}]",
                    f"must divide the unit square into whole cells (1/dx integer), got {dx}")
            require(self.dx.index(dx) == i, f"dx[{i}]", f"{dx} appears twice (each run would be listed twice)")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.material.eta > 0, "material.eta",
                "must be positive: the Taylor-Green reference decay exp(-8 pi^2 t / Re) and Re = rho_ref u_ref / eta "
                f"need a viscosity, got {self.material.eta}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        for i, t in enumerate(self.eval_times):
            require(t >= 0, f"eval_times[{i}]", f"must be >= 0, got {t}")
        check_output(self)
        require(self.fig4_method in names, "fig4_method", f"{self.fig4_method!r} is not one of the methods {names}")

    @property
    def re(self) -> float:
        """Reynolds number rho U L / eta with L = 1 (the unit square)."""
        return self.material.rho_ref * self.material.u_ref / self.material.eta


@dataclass(frozen=True)
class Run:
    """One method at one spacing: everything its numbers depend on (its cache key with the code)."""

    name: str
    case: str
    method: str
    effects: Effects
    dx: float
    material: Material
    numerics: Numerics
    t_end: float
    frames: int
    keep: tuple[str, ...]
    connectivity_radius_factor: float
    relaxation: Relaxation
    eval_times: tuple[float, ...] = field(default=(), metadata={"key": False})

    @property
    def re(self) -> float:
        return self.material.rho_ref * self.material.u_ref / self.material.eta


def run_name(method: str, dx: float) -> str:
    return f"{method}_{dx_tag(dx)}"


def runs(s: Settings) -> list:
    return [Run(run_name(m.name, dx), s.case, m.name, m.effects, dx, s.material, s.numerics, s.t_end, s.frames,
                s.keep, s.connectivity_radius_factor, s.relaxation, s.eval_times)
            for dx in s.dx for m in s.methods]


def preflight(runs) -> None:
    """Every spacing about to run against the available memory, before anything is relaxed or run."""
    for r in {r.dx: r for r in runs}.values():
        check_fits(f"tgv2d at dx = {r.dx:g}", count([0.0, 0.0], list(tgv.BOX), r.dx), 2, r.dx, r.numerics)


def start(run: Run) -> Start:
    """The relaxed start of the run's spacing (sph.cases.tgv.relax), shared by its methods."""
    def compute(progress):
        return tgv.relax(run.dx, run.material, run.numerics, run.relaxation, progress, desc=f"relax {dx_tag(run.dx)}")

    return Start(dx_tag(run.dx), {"dx": run.dx, "material": run.material, "numerics": run.numerics,
                                  "relaxation": run.relaxation}, compute,
                 meta={"dx": run.dx, "relaxation": dataclasses.asdict(run.relaxation)})


def scene(run: Run, r: np.ndarray):
    return tgv.scene(run.dx, run.material, run.effects, r=r), run.numerics


def run_options(run: Run) -> dict:
    return {"case": run.case, "keep": run.keep, "connectivity_radius_factor": run.connectivity_radius_factor,
            "u_limit": run.numerics.c_ref_factor * run.material.u_ref,
            "metadata": {"re": run.re, "relaxation": dataclasses.asdict(run.relaxation)}}


def metrics(run: Run, traj: dict) -> dict:
    meta, attrs = traj["metadata"], traj["attrs"]
    t, u, e = traj["time"], traj["u_max"], traj["e_kin"]
    n_steps = int(attrs["n_steps"])
    row = {"case": run.case, "method": run.method, "dx": run.dx, "dtype": run.numerics.dtype,
           "n_particles": int(traj["particle_type"].shape[0]), "n_steps": n_steps, "dt": meta["dt"],
           "t_end": float(t[-1]), "write_every": meta["write_every"], "n_frames": int(t.shape[0]),
           "wall_s": float(attrs["wall_s"]), "compile_s": float(attrs["compile_s"]),
           "ms_per_step": 1e3 * float(attrs["wall_s"]) / n_steps if n_steps else np.nan,
           "n_reallocations": int(attrs["n_reallocations"])}
    for name, sim, exact in (("u_max", u, tgv.u_max_exact), ("e_kin", e, tgv.e_kin_exact)):
        for te in run.eval_times:
            val = np.interp(te, t, sim) if te <= t[-1] * (1 + 1e-9) else np.nan
            row[f"{name}_relerr_t{te:g}"] = abs(val / exact(te, run.re) - 1.0) if np.isfinite(val) else np.nan
    for name, rel in tgv.decay_errors(t, u, e, run.re).items():
        row[f"{name}_relerr_mean"] = float(np.trapezoid(rel, t) / (t[-1] - t[0])) if t[-1] > t[0] else float(rel[0])
    row["density_error_max"] = float(np.max(traj["density_error"]))
    return row


def record(run: Run, m: dict) -> dict:
    return {"errors": {"u_max_mean": m["u_max_relerr_mean"], "e_kin_mean": m["e_kin_relerr_mean"],
                       **{f"u_max_t{te:g}": m[f"u_max_relerr_t{te:g}"] for te in run.eval_times}}}
