"""The 3D Taylor-Green study (JAX-SPH Fig. 9, Re = 100; the protocol is lab.experiment's): every
(resolution, method) of a profile, `<method>_n<n>` (n^3 particles, dx = 2 pi / n), each method's effects
on the analytical TGV velocity over the start of its resolution: the relaxed lattice (`start`, cached
relaxed_n<n>.npy; the relaxation of tgv2d, sph.cases.tgv3d.relax) or the bare lattice. What a run
measures against the JAX-Fluids reference is analysis.py (out of the runs' keys: the paper profile
takes hours).
"""
import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import sph
from sph.cases import tgv3d
from sph.relax import Relaxation
from lab.configtools import require, require_agree, require_finite
from lab.protocol import Start
from lab.runs import check_fits
from lab.study import Method, check_methods, check_output

ROOT = Path(__file__).resolve().parents[2]
STARTS = ("relaxed", "lattice")
MIN_N_SIDE = 6
"""The periodic side 2 pi must be at least twice the quintic support 3 dx (sph.solver.check_resolution)."""


@dataclass(frozen=True)
class Analysis:
    """Post-processing of the stored frames (analysis.py; not part of the run fingerprint: editing it
    re-evaluates the runs without re-running them).

    dissipation_span  time between the two frames of the central difference -dE/dt(t_k) =
                      -(E_{k+j} - E_{k-j}) / (t_{k+j} - t_{k-j}), j = max(1, round(span / (2 frame spacing)));
                      0 = the neighbouring frames. About one acoustic period or more filters the sound
                      waves of the weakly compressible start (period 2 pi / (|k| c_ref) = 0.31 and 0.22
                      for the |k| = 2 and 2 sqrt(2) modes of the TGV pressure at c_ref = 10), which
                      otherwise swing the frame-to-frame rate by about as much as the dissipation itself
    early_window      the early decay rate is minus the least-squares slope of E_kin over [0, early_window]
    """

    dissipation_span: float = 0.5
    early_window: float = 1.0

    def __post_init__(self):
        require_finite(self, "analysis")
        require(self.dissipation_span >= 0, "analysis.dissipation_span", f"must be >= 0, got {self.dissipation_span}")
        require(self.early_window > 0, "analysis.early_window", f"must be positive, got {self.early_window}")


@dataclass(frozen=True)
class Settings:
    """One profile of the experiment (see config.yaml for the meaning of each key)."""

    methods: tuple[Method, ...]
    n_side: tuple[int, ...]
    t_end: float
    case: str = "tgv3d"
    material: sph.Material = field(default_factory=sph.Material)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    frames: int = 200
    keep: tuple[str, ...] = ()
    connectivity_radius_factor: float = 1.45
    start: str = "relaxed"
    relaxation: Relaxation = field(default_factory=Relaxation)
    reference: str = "validation_refs/tgv3d_ref_100.txt"
    reference_re: float = 100.0
    analysis: Analysis = field(default_factory=Analysis)

    def __post_init__(self):
        require_finite(self)
        check_methods(self.methods)
        require(len(self.n_side) > 0, "n_side", "needs at least one resolution (particles per side)")
        for i, n in enumerate(self.n_side):
            require(n >= MIN_N_SIDE, f"n_side[{i}]",
                    f"must be >= {MIN_N_SIDE}: the box side 2 pi must be at least twice the kernel support 3 dx, got {n}")
            require(self.n_side.index(n) == i, f"n_side[{i}]", f"{n} appears twice")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.frames >= 4, "frames", f"must be >= 4 (dE/dt by central differences), got {self.frames}")
        check_output(self)
        require(self.start in STARTS, "start", f"{self.start!r} is not one of {list(STARTS)}")
        require(self.material.eta > 0, "material.eta",
                f"must be positive: Re = rho_ref u_ref / eta needs a viscosity, got {self.material.eta}")
        require(abs(self.re - self.reference_re) <= 1e-9 * self.reference_re, "material.eta",
                f"Re = rho_ref u_ref / eta = {self.re:g} differs from reference_re = {self.reference_re:g}: the "
                "runs would be compared with the wrong reference")
        require(self.reference_file.is_file(), "reference", f"{self.reference_file} does not exist")
        require_agree(self.analysis.dissipation_span < self.t_end / 2, ("analysis.dissipation_span", "t_end"),
                      f"must be below t_end / 2 = {self.t_end / 2:g} (the central difference needs frames on both "
                      f"sides), got {self.analysis.dissipation_span}")

    @property
    def re(self) -> float:
        """Reynolds number rho U L / eta with L = 1 (the box is 2 pi L)."""
        return self.material.rho_ref * self.material.u_ref / self.material.eta

    @property
    def nu(self) -> float:
        return self.material.eta / self.material.rho_ref

    def dx(self, n: int) -> float:
        return tgv3d.dx_for(n)

    @property
    def reference_file(self) -> Path:
        """The reference file (`reference`, relative to the repository)."""
        p = Path(self.reference)
        return p if p.is_absolute() else ROOT / p


@dataclass(frozen=True)
class Run:
    """One method at n^3 particles: everything its numbers depend on (its cache key with the code and
    its start's; `settings`, read by the analysis only, stays out of the key)."""

    name: str
    case: str
    method: str
    effects: sph.Effects
    n_side: int
    material: sph.Material
    numerics: sph.Numerics
    t_end: float
    frames: int
    keep: tuple[str, ...]
    connectivity_radius_factor: float
    start: str
    relaxation: Optional[Relaxation]
    settings: Settings = field(metadata={"key": False})

    @property
    def dx(self) -> float:
        return tgv3d.dx_for(self.n_side)

    @property
    def re(self) -> float:
        return self.material.rho_ref * self.material.u_ref / self.material.eta


def run_name(method: str, n: int) -> str:
    return f"{method}_n{n}"


def runs(s: Settings) -> list:
    relaxation = s.relaxation if s.start == "relaxed" else None
    return [Run(run_name(m.name, n), s.case, m.name, m.effects, n, s.material, s.numerics, s.t_end, s.frames, s.keep,
                s.connectivity_radius_factor, s.start, relaxation, s)
            for n in s.n_side for m in s.methods]


def preflight(runs) -> None:
    """Every resolution about to run against the available memory, before anything is relaxed or run."""
    for r in {r.n_side: r for r in runs}.values():
        n = r.n_side
        check_fits(f"tgv3d at n = {n} ({n ** 3:,} particles)", n ** 3, 3, r.dx, r.numerics)


def start(run: Run) -> Optional[Start]:
    """The relaxed start of the run's resolution (sph.cases.tgv3d.relax, as tgv2d), shared by its
    methods; None (the scene's lattice) for `start: lattice`."""
    if run.start != "relaxed":
        return None

    def compute(progress):
        return tgv3d.relax(run.dx, run.material, run.numerics, run.relaxation, progress, desc=f"relax n{run.n_side}")

    return Start(f"n{run.n_side}", {"n_side": run.n_side, "material": run.material, "numerics": run.numerics,
                                    "relaxation": run.relaxation}, compute,
                 meta={"n_side": run.n_side, "dx": run.dx, "relaxation": dataclasses.asdict(run.relaxation)})


def scene(run: Run, r=None):
    return tgv3d.scene(run.dx, run.material, run.effects, r=r), run.numerics


def run_options(run: Run) -> dict:
    return {"case": run.case, "keep": run.keep, "connectivity_radius_factor": run.connectivity_radius_factor,
            "u_limit": run.numerics.c_ref_factor * run.material.u_ref,
            "metadata": {"re": run.re, "n_side": run.n_side, "start": run.start,
                         "relaxation": dataclasses.asdict(run.relaxation) if run.relaxation else None}}
