"""Settings of the thermal experiments: config.yaml -> frozen, validated dataclasses, result paths
and the fingerprints that decide whether a cached run still matches its inputs.

Two studies share the file: `diffusion` (the heat operator against the analytical decay of a
sinusoidal temperature in a periodic box at rest) and `channel` (JAX-SPH's hot channel, Fig. 10).
"""
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

import sph
from lab.configtools import load_profile, require, require_finite, to_mapping
from lab.keys import digest
from lab.layout import Study, dx_tag

HERE = Path(__file__).resolve().parent
NAME = HERE.name
ROOT = HERE.parents[1]
CONFIG = HERE / "config.yaml"
THERMAL_MATERIAL = sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0, kappa=7.313, c_p=305.27)


def _whole_cells(length: float, dx: float) -> bool:
    if not dx > 0:
        return False
    n = length / dx
    return round(n) >= 1 and abs(n - round(n)) < 1e-6


def _needs_heat_material(mat: sph.Material, where: str):
    require(mat.kappa is not None, f"{where}.material.kappa", "the heat equation needs a thermal conductivity")
    require(mat.c_p is not None, f"{where}.material.c_p", "the heat equation needs a specific heat capacity")


@dataclass(frozen=True)
class Diffusion:
    """T = T0 + amplitude sin(2 pi mode x / 1) in the periodic unit square, fluid at rest on a
    uniform lattice; exact decay of the amplitude exp(-alpha k^2 t), alpha = kappa / (rho_ref c_p),
    k = 2 pi mode. The full solver step runs (heat + momentum, particles free to move).

    dx             spacings of the convergence study
    report_dx      the spacing whose error is the headline number (and checked against target_relerr)
    frames         amplitude samples after t = 0
    target_relerr  |A_sim / A_exact - 1| at t_end that the report_dx run must meet
    """

    dx: tuple[float, ...]
    t_end: float
    report_dx: float
    material: sph.Material = THERMAL_MATERIAL
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    T0: float = 1.0
    amplitude: float = 0.1
    mode: int = 1
    frames: int = 20
    target_relerr: float = 0.01

    def __post_init__(self):
        require_finite(self, "diffusion")
        require(len(self.dx) > 0, "diffusion.dx", "needs at least one spacing")
        for i, dx in enumerate(self.dx):
            require(_whole_cells(1.0, dx), f"diffusion.dx[{i}]",
                    f"must divide the unit square into whole cells (1/dx integer), got {dx}")
            require(self.dx.index(dx) == i, f"diffusion.dx[{i}]", f"{dx} appears twice")
        require(any(abs(d - self.report_dx) < 1e-12 for d in self.dx), "diffusion.report_dx",
                f"{self.report_dx} is not one of diffusion.dx {list(self.dx)}")
        require(self.t_end > 0, "diffusion.t_end", f"must be positive, got {self.t_end}")
        require(self.amplitude != 0, "diffusion.amplitude", "must be non-zero")
        require(self.mode >= 1, "diffusion.mode", f"must be >= 1, got {self.mode}")
        require(self.frames >= 1, "diffusion.frames", f"must be >= 1, got {self.frames}")
        require(self.target_relerr > 0, "diffusion.target_relerr", f"must be positive, got {self.target_relerr}")
        _needs_heat_material(self.material, "diffusion")

    @property
    def alpha(self) -> float:
        return self.material.kappa / (self.material.rho_ref * self.material.c_p)

    @property
    def k(self) -> float:
        return 2.0 * math.pi * self.mode

    def amplitude_exact(self, t):
        return self.amplitude * np.exp(-self.alpha * self.k**2 * np.asarray(t))


@dataclass(frozen=True)
class Channel:
    """JAX-SPH's hot channel (cases/ht.py, ht.yaml); see config.yaml and sph/cases/channel.py."""

    dx: float
    t_end: float
    material: sph.Material = THERMAL_MATERIAL
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    effects: sph.Effects = field(default_factory=lambda: sph.Effects(walls="no_slip", heat=True,
                                                                     gravity=(2.3, 0.0)))
    length: float = 1.0
    height: float = 0.2
    wall_layers: int = 3
    noise_factor: float = 0.05
    seed: int = 123
    T_ref: float = 1.0
    T_hot: float = 1.23
    hot_half_width: float = 0.25
    zone_layers: int = 3
    frames: int = 60
    snapshot_times: tuple[float, ...] = (0.0, 0.3, 0.6, 0.9, 1.2, 1.5)
    max_principle_tol: float = 1e-9

    def __post_init__(self):
        require_finite(self, "channel")
        require(self.material.eta > 0, "channel.material.eta",
                "must be positive: the channel's laminar reference (Poiseuille start-up, u_bulk = g H^2 / (12 nu)) "
                f"needs a viscosity, got {self.material.eta}")
        fx = self.effects
        require(fx.heat, "channel.effects.heat", "the hot channel needs effects.heat: true")
        require(fx.walls is not None, "channel.effects.walls", "the channel needs walls (no_slip)")
        require(fx.gravity is not None and len(fx.gravity) == 2, "channel.effects.gravity",
                "the channel is driven by a 2D body force, e.g. [2.3, 0.0]")
        _needs_heat_material(self.material, "channel")
        require(_whole_cells(self.length, self.dx), "channel.dx",
                f"must divide channel.length = {self.length} into whole cells, got {self.dx}")
        require(_whole_cells(self.height, self.dx), "channel.dx",
                f"must divide channel.height = {self.height} into whole cells, got {self.dx}")
        require(self.wall_layers >= 1, "channel.wall_layers", f"must be >= 1, got {self.wall_layers}")
        require(self.zone_layers >= 0, "channel.zone_layers", f"must be >= 0, got {self.zone_layers}")
        require(self.T_hot > self.T_ref, "channel.T_hot", f"must exceed T_ref = {self.T_ref}, got {self.T_hot}")
        require(0 < self.hot_half_width <= self.length / 2, "channel.hot_half_width",
                f"must be in (0, length/2], got {self.hot_half_width}")
        require(self.t_end > 0, "channel.t_end", f"must be positive, got {self.t_end}")
        require(self.frames >= 1, "channel.frames", f"must be >= 1, got {self.frames}")
        require(len(self.snapshot_times) > 0, "channel.snapshot_times", "needs at least one time")
        for i, t in enumerate(self.snapshot_times):
            require(0 <= t <= self.t_end * (1 + 1e-9), f"channel.snapshot_times[{i}]",
                    f"{t} lies outside [0, t_end = {self.t_end}]")
        require(self.max_principle_tol >= 0, "channel.max_principle_tol", "must be >= 0")

    @property
    def alpha(self) -> float:
        return self.material.kappa / (self.material.rho_ref * self.material.c_p)

    @property
    def nu(self) -> float:
        return self.material.eta / self.material.rho_ref

    @property
    def g(self) -> float:
        return float(self.effects.gravity[0])


@dataclass(frozen=True)
class Experiment:
    diffusion: Diffusion
    channel: Channel


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Experiment:
    """Parse `profile` of config file `path`; `overrides` (a mapping) is merged over it last."""
    return load_profile(Experiment, path, profile, overrides)


# -- paths and code key (lab.layout) -------------------------------------------------------
STUDY = Study(NAME, HERE)
"""results/<profile>/thermal/{sine,channel}_dx<dx>/ per run, metrics.csv beside them; the code key of
settings.py and run.py with the sph modules they and the solver import."""
out_dir, metrics_path = STUDY.out_dir, STUDY.metrics_path


def sine_dir(results, dx: float) -> Path:
    return STUDY.run_dir(results, "sine", dx_tag(dx))


def channel_dir(results, dx: float) -> Path:
    return STUDY.run_dir(results, "channel", dx_tag(dx))


# -- fingerprints ---------------------------------------------------------------------------------
def sine_fingerprint(d: Diffusion, dx: float) -> str:
    cfg = {k: v for k, v in to_mapping(d).items() if k not in ("dx", "report_dx", "target_relerr")}
    return digest({"study": "sine", "dx": dx, "cfg": cfg, "code": STUDY.code_hash("run.py")})


def channel_fingerprint(c: Channel) -> str:
    return digest({"study": "channel", "cfg": to_mapping(c), "code": STUDY.code_hash("run.py")})
