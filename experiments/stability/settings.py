"""Settings of the stability suite: config.yaml -> frozen, validated dataclasses, result paths and
the fingerprints that decide whether a cached case result still matches its inputs.

A profile is `{inherit?, defaults, cases}`: `cases` maps a case name to its settings, `defaults` is
merged under every case (key by key, so a case overrides single numerics or criteria keys), and
`inherit: <profile>` merges the whole profile over another one, so the smoke profile only names what
it shrinks. An unknown or mistyped key fails with a message naming it, e.g.
"profiles.smoke.cases.ldc_tvf.t_edn: unknown key".
"""
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import sph
from lab.configtools import (ConfigError, from_mapping, merge, profile_mapping, require, require_finite,
                                     require_name, to_mapping)
from lab.keys import code_fingerprint, digest
from sph.relax import Relaxation

HERE = Path(__file__).resolve().parent
NAME = HERE.name
ROOT = HERE.parents[1]
CONFIG = HERE / "config.yaml"
KINDS = ("dam_break", "ldc", "tgv", "heat")
STARTS = ("lattice", "jitter", "relaxed")
TEMPERATURES = ("sine", "step")
EXPECTED = ("pass", "fail", "unknown")


@dataclass(frozen=True)
class Criteria:
    """Pass/fail thresholds of a case. A case passes when its fields stay finite to t_end (always
    required) and every check that is set holds; null switches a check off.

    density_error_max   max over fluid particles and frames of |rho/rho_ref - 1|
    no_crossing         no fluid particle ever beyond a wall face by more than dx/2, or outside the box
    energy_rise_max     dam break: max over frames of (E(t) - min_{s <= t} E(s)) / E(0), E = E_kin + E_pot
                        (dissipated: it may rise only by what the compressed fluid gives back)
    ekin_relerr_max     TGV: max over frames of |E_kin / E_kin_exact - 1| while E_kin_exact >= 0.2 E_kin_exact(0)
                        (t <= 1 at Re = 100; later the decayed vortex makes the ratio meaningless)
    ekin_rise_max       TGV: max over frames of (E_kin(t) - min_{s <= t} E_kin(s)) / E_kin_exact(0): the
                        decaying vortex must not gain kinetic energy (lattice collapse, spurious motion)
    thermal_drift_max   heat: max over frames of |E_th / E_th(0) - 1|, E_th = sum m c_p T
    overshoot_max       heat: largest excursion of T beyond its initial [min, max] / (max - min)
    dt_limit            the time-step limit that must be the binding one (e.g. "thermal"), or null
    rest_speed_max      tank at rest (a dam_break case whose column fills the tank's width): max |u| of
                        the fluid over the last quarter of the run / sqrt(g H), H the column height
    """

    density_error_max: Optional[float] = 0.05
    no_crossing: bool = True
    energy_rise_max: Optional[float] = None
    ekin_relerr_max: Optional[float] = None
    ekin_rise_max: Optional[float] = None
    thermal_drift_max: Optional[float] = None
    overshoot_max: Optional[float] = None
    dt_limit: Optional[str] = None
    rest_speed_max: Optional[float] = None


@dataclass(frozen=True)
class Case:
    """One stability case (see config.yaml for the meaning of each key)."""

    kind: str
    dx: float
    t_end: float
    effects: sph.Effects = field(default_factory=sph.Effects)
    material: sph.Material = field(default_factory=sph.Material)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    criteria: Criteria = field(default_factory=Criteria)
    expected: str = "pass"
    note: str = ""
    frames: int = 200
    stored_frames: int = 20
    # dam break: water column (width, height) in a tank (length, height); gravity from effects.gravity
    column: tuple[float, float] = (2.0, 1.0)
    tank: tuple[float, float] = (5.366, 2.0)
    hydrostatic_init: bool = True  # start from p = rho g (H - y) (sph.cases.tank.hydrostatic), as make fig8
    # lid-driven cavity
    lid_velocity: float = 1.0
    # Taylor-Green vortex: initial positions
    start: str = "lattice"
    jitter: float = 0.0
    seed: int = 0
    relaxation: Relaxation = field(default_factory=Relaxation)
    # heat: T = T0 + dT sin(2 pi x) ("sine") or T0 + dT for x < 1/2 ("step"), fluid at rest
    temperature: str = "sine"
    T0: float = 1.0
    dT: float = 1.0

    def __post_init__(self):
        require_finite(self)
        require(self.kind in KINDS, "kind", f"{self.kind!r} is not one of {KINDS}")
        require(self.dx > 0, "dx", f"must be positive, got {self.dx}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.expected in EXPECTED, "expected", f"{self.expected!r} is not one of {EXPECTED}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        require(self.stored_frames >= 1, "stored_frames", f"must be >= 1, got {self.stored_frames}")
        require(self.start in STARTS, "start", f"{self.start!r} is not one of {STARTS}")
        require(self.jitter >= 0, "jitter", f"must be >= 0, got {self.jitter}")
        require(self.temperature in TEMPERATURES, "temperature", f"{self.temperature!r} is not one of {TEMPERATURES}")
        fx = self.effects
        if self.kind in ("tgv", "heat"):
            require(abs(1.0 / self.dx - round(1.0 / self.dx)) < 1e-6, "dx",
                    f"must divide the periodic unit square into whole cells (1/dx integer), got {self.dx}")
            require(fx.walls is None and fx.gravity is None, "effects",
                    f"a {self.kind} case is a periodic box without walls or gravity")
        if self.kind in ("dam_break", "ldc"):
            require(fx.walls is not None, "effects.walls", f"a {self.kind} case needs walls (no_slip or free_slip)")
        if self.kind == "dam_break":
            require(fx.gravity is not None and len(fx.gravity) == 2 and fx.gravity[1] < 0 and fx.gravity[0] == 0,
                    "effects.gravity", "the dam break needs gravity [0, -g] with g > 0")
            require(self.column[0] <= self.tank[0] and self.column[1] <= self.tank[1], "column",
                    f"the water column {self.column} does not fit into the tank {self.tank}")
        require(self.kind == "heat" or not fx.heat, "effects.heat", "only the heat case carries a temperature")
        if self.kind == "heat":
            require(fx.heat, "effects.heat", "the heat case needs effects.heat: true")
            require(self.dT > 0, "dT", f"must be positive, got {self.dT}")

    @property
    def re(self) -> float:
        """rho_ref u_ref L / eta with L = 1 (TGV box, cavity side)."""
        m = self.material
        return m.rho_ref * m.u_ref / m.eta if m.eta > 0 else float("inf")


@dataclass(frozen=True)
class Suite:
    profile: str
    cases: tuple  # ((name, Case), ...) in config order

    def names(self) -> list:
        return [n for n, _ in self.cases]

    def case(self, name: str) -> Case:
        for n, c in self.cases:
            if n == name:
                return c
        raise KeyError(f"no case {name!r} in profile {self.profile} (cases: {', '.join(self.names())})")


def load(profile: str, path=CONFIG, overrides: Optional[dict] = None) -> Suite:
    """Parse `profile` of `path`; `overrides` ({defaults: ..., cases: {name: ...}}) is merged last, so
    a test can add a case or shrink one."""
    raw = profile_mapping(path, profile, overrides)
    where = f"profiles.{profile}"
    unknown = sorted(set(raw) - {"defaults", "cases"})
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]}: unknown key (known keys: cases, defaults, inherit)")
    defaults, cases = raw.get("defaults") or {}, raw.get("cases") or {}
    for key, val in (("defaults", defaults), ("cases", cases)):
        if not isinstance(val, dict):
            raise ConfigError(f"{where}.{key}: expected a mapping, got {val!r}")
    if not cases:
        raise ConfigError(f"{where}.cases: no cases")
    parsed = []
    for name, spec in cases.items():
        if spec is None:  # `name: null` in an inheriting profile drops the case
            continue
        if not isinstance(spec, dict):
            raise ConfigError(f"{where}.cases.{name}: expected a mapping, got {spec!r}")
        require_name(str(name), f"{where}.cases.{name}")  # the case's folder name
        parsed.append((str(name), from_mapping(Case, merge(defaults, spec), f"{where}.cases.{name}")))
    return Suite(profile=profile, cases=tuple(parsed))


# -- paths ----------------------------------------------------------------------------------------
def out_dir(results) -> Path:
    """results/<profile>/stability."""
    return Path(results) / NAME


def case_dir(results, name: str) -> Path:
    return out_dir(results) / name


def table_path(results) -> Path:
    return out_dir(results) / "stability.csv"


def markdown_path(results) -> Path:
    return out_dir(results) / "stability.md"


# -- fingerprints ---------------------------------------------------------------------------------
def code_hash() -> str:
    """Hash of what produces a case's metrics: the solver's physics modules and those cases.py
    imports (sph.relax among them), cases.py and settings.py (lab.keys.code_fingerprint). run.py
    (evaluation, table) is left out: it re-evaluates stored metrics and never changes them."""
    return code_fingerprint([HERE / n for n in ("settings.py", "cases.py")])


NOT_SIMULATED = ("criteria", "expected", "note")
"""Case keys that only judge a result; changing them re-evaluates the table without re-running."""


def case_fingerprint(name: str, case: Case, code: bool = True) -> str:
    """What a case's metrics depend on: its simulation settings and (unless `code` is false) the code."""
    settings = {k: v for k, v in to_mapping(case).items() if k not in NOT_SIMULATED}
    return digest({"name": name, "case": settings, **({"code": code_hash()} if code else {})})
