"""Settings of the 3D Taylor-Green experiment: config.yaml -> frozen, validated dataclasses, paths,
the reference file (read by analysis.py: sph.cases.tgv3d_reference), and the fingerprints that decide whether a cached result still matches its inputs.
What it shares with the 2D study (methods, paths, cache keys, relaxed starts, runs) is
lab.study's."""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import sph
from sph.cases import tgv3d
from lab.configtools import load_profile, require, require_agree, require_finite, to_mapping
from lab.keys import digest
from lab.layout import Study
from lab.study import Method, check_methods, check_output
from sph.relax import Relaxation  # noqa: F401  (the relaxation settings of this experiment)

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
NAME = HERE.name
"""The experiment's name is its folder's: results go to results/<profile>/<NAME>."""
CONFIG = HERE / "config.yaml"
STUDY = Study(NAME, HERE)
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
class Experiment:
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
        require(reference_path(self).is_file(), "reference", f"{reference_path(self)} does not exist")
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

    def method(self, name: str) -> Method:
        return next(m for m in self.methods if m.name == name)


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return load_profile(Experiment, path, profile, overrides)


# -- reference ------------------------------------------------------------------------------------
def reference_path(exp: Experiment) -> Path:
    p = Path(exp.reference)
    return p if p.is_absolute() else ROOT / p


# -- paths ----------------------------------------------------------------------------------------
def n_tag(n: int) -> str:
    return f"n{n}"


def out_dir(results) -> Path:
    """results/<profile>/<NAME> (tgv3d for this folder)."""
    return STUDY.out_dir(results)


def run_dir(results, method: str, n: int) -> Path:
    return STUDY.run_dir(results, method, n_tag(n))


def relaxed_path(results, n: int) -> Path:
    return STUDY.relaxed_path(results, n_tag(n))


def metrics_path(results) -> Path:
    return STUDY.metrics_path(results)


# -- fingerprints ---------------------------------------------------------------------------------
RELAX_MODULES = ("sph.cases.tgv3d",)
"""The code of a relaxed start besides the solver's (the 3D TGV scene and its relaxation, sph.cases.relaxed)."""


def relax_fingerprint(exp: Experiment, n: int) -> str:
    """The relaxed start of n^3 particles: its settings and the code that relaxes (the solver's, the
    case's relaxation and scene, settings.py), without docstrings or comments."""
    return digest({"n_side": n, "material": to_mapping(exp.material), "numerics": to_mapping(exp.numerics),
                   "relaxation": to_mapping(exp.relaxation), "code": STUDY.code_hash(modules=RELAX_MODULES)})


def run_fingerprint(exp: Experiment, method: Method, n: int) -> str:
    """The run of `method` at n^3 particles: its settings, its start and the code of the solver, of
    settings.py and run.py and of the sph modules they import (analysis.py, which only evaluates, is
    not part of it)."""
    start = relax_fingerprint(exp, n) if exp.start == "relaxed" else "lattice"
    return digest({"case": exp.case, "n_side": n, "method": to_mapping(method), "material": to_mapping(exp.material),
                   "numerics": to_mapping(exp.numerics), "t_end": exp.t_end, "frames": exp.frames,
                   "keep": list(exp.keep), "start": start, "code": STUDY.code_hash("run.py")})
