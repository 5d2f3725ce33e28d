"""The 2D lid-driven cavity (JAX-SPH Figs. 6-7, Re = 100, against Ghia et al. 1982; the protocol is
lab.experiment's): every (dx, method) of a profile, `<method>_dx<dx>`, from the Cartesian lattice at rest
(sph.cases.ldc: three layers of wall particles, the top ones moving at the lid speed) to t_end. With
`lid_corners: fixed` (the validated set-up) the wall particles of the top layers beyond the side walls
are fixed walls, so the lid spans exactly the cavity width; `moving` is JAX-SPH's full-width lid (why:
sph.cases.ldc.LID_CORNERS). Each figure has its own runs (its dx): a run's `groups` are the figures
that show it (make fig6 runs only Fig. 6's). What a run measures (centreline profiles against Ghia) is
analysis.py, out of the runs' keys: editing it re-evaluates the runs without re-running them.
"""
from dataclasses import dataclass, field

import sph
from sph.cases import ldc
from lab.configtools import from_mapping, merge, require, require_agree, require_finite, to_mapping
from lab.layout import dx_tag
from lab.runs import check_fits

KEEPABLE = ("velocity", "momentum_velocity", "density", "pressure")
FIGURES = ("fig6", "fig7")
VELOCITIES = ("transport", "momentum")
LID_CORNERS = ldc.LID_CORNERS
WALL_MODES = ("fluid", "mirror")


@dataclass(frozen=True)
class Method:
    """A named solver variant: the effects its scene declares (`effects.walls` defaults to no-slip)
    and optional overrides of the profile's numerics (e.g. `{p_bg_factor: 0.01}` for standard SPH)."""

    name: str
    effects: dict = field(default_factory=dict)
    numerics: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Analysis:
    """How the centreline profiles are taken from the particles (post-processing only).

    average_frames  profiles are averaged over this many frames at the end of the run (t_end included)
    velocity        'transport' (v, the particles' velocity; = u without TVF) or 'momentum' (u)
    walls           'fluid': Shepard interpolation over fluid particles only; 'mirror': the wall
                    particles also contribute, with the no-slip velocity of the generalized wall
                    condition (Adami 2012, 2 u_wall - Shepard average of the fluid around the wall
                    particle), i.e. the velocity the solver itself gives the walls in the viscous term
    n_points        points per centreline for the plotted curves (the metrics use Ghia's 17 points)
    steady_window   steadiness check: relative change between the mean E_kin over the last
                    `steady_window` time units and over the window before
                    (sph.cases.ldc_reference.window_change), and the profile change between the last
                    two averaging windows
    """

    average_frames: int = 20
    velocity: str = "transport"
    walls: str = "mirror"
    n_points: int = 101
    steady_window: float = 5.0

    def __post_init__(self):
        require_finite(self, "analysis")
        require(self.average_frames >= 1, "analysis.average_frames", f"must be >= 1, got {self.average_frames}")
        require(self.velocity in VELOCITIES, "analysis.velocity", f"{self.velocity!r} is not one of {list(VELOCITIES)}")
        require(self.walls in WALL_MODES, "analysis.walls", f"{self.walls!r} is not one of {list(WALL_MODES)}")
        require(self.n_points >= 2, "analysis.n_points", f"must be >= 2, got {self.n_points}")
        require(self.steady_window > 0, "analysis.steady_window", f"must be positive, got {self.steady_window}")


@dataclass(frozen=True)
class Settings:
    """One profile of the experiment (see config.yaml for the meaning of each key)."""

    methods: tuple[Method, ...]
    figures: dict
    t_end: float
    case: str = "ldc2d"
    material: sph.Material = field(default_factory=sph.Material)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    lid_velocity: float = 1.0
    wall_layers: int = 3
    lid_corners: str = "fixed"
    frames: int = 200
    keep: tuple[str, ...] = ("velocity", "momentum_velocity", "density")
    connectivity_radius_factor: float = 1.45
    analysis: Analysis = field(default_factory=Analysis)
    ghia_re: int = 100

    def __post_init__(self):
        require_finite(self)
        require(len(self.methods) > 0, "methods", "needs at least one method")
        names = [m.name for m in self.methods]
        for i, n in enumerate(names):
            require(names.index(n) == i, f"methods[{i}].name", f"{n!r} appears twice")
        for i, m in enumerate(self.methods):
            fx = self.effects(m, where=f"methods[{i}]")
            require(fx.walls == "no_slip", f"methods[{i}].effects.walls",
                    f"the cavity walls are no-slip; got {fx.walls!r}")
            self.numerics_of(m, where=f"methods[{i}]")
        unknown = sorted(set(self.figures) - set(FIGURES))
        require(not unknown, f"figures.{unknown[0] if unknown else ''}", f"unknown figure (known: {list(FIGURES)})")
        require(len(self.figures) > 0, "figures", f"needs at least one of {list(FIGURES)} with its dx")
        for name, dx in self.figures.items():
            require(isinstance(dx, (int, float)) and not isinstance(dx, bool), f"figures.{name}",
                    f"expected a particle spacing, got {dx!r}")
            require(dx > 0 and abs(1.0 / dx - round(1.0 / dx)) < 1e-6, f"figures.{name}",
                    f"must divide the unit cavity into whole cells (1/dx integer), got {dx}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        require(self.lid_velocity > 0, "lid_velocity", f"must be positive, got {self.lid_velocity}")
        require_agree(self.lid_velocity <= self.material.u_ref, ("lid_velocity", "material.u_ref"),
                      f"must not exceed material.u_ref ({self.material.u_ref}), which sets the sound speed")
        require(self.wall_layers >= 1, "wall_layers", f"must be >= 1, got {self.wall_layers}")
        require(self.lid_corners in LID_CORNERS, "lid_corners",
                f"{self.lid_corners!r} is not one of {list(LID_CORNERS)}")
        for i, k in enumerate(self.keep):
            require(k in KEEPABLE, f"keep[{i}]", f"{k!r} is not one of {list(KEEPABLE)}")
        for k in ("velocity", "density"):
            require(k in self.keep, "keep", f"the profiles need {k!r} in keep")
        if self.analysis.velocity == "momentum":
            require("momentum_velocity" in self.keep, "analysis.velocity",
                    "'momentum' needs 'momentum_velocity' in keep")
        require(self.analysis.average_frames <= self.frames + 1, "analysis.average_frames",
                f"must not exceed the number of frames ({self.frames} + 1)")
        require(self.material.eta > 0, "material.eta",
                f"must be positive: the cavity's Re = rho_ref lid_velocity / eta needs a viscosity, got {self.material.eta}")
        require(self.ghia_re in ldc.GHIA_RE, "ghia_re",
                f"not a Reynolds number of Ghia's tables, got {self.ghia_re}")
        require_agree(abs(self.re - self.ghia_re) <= 1e-9 * self.ghia_re,
                      ("ghia_re", "material.eta", "material.rho_ref", "lid_velocity"),
                      f"Re = rho_ref lid_velocity / eta = {self.re:g} differs from ghia_re = {self.ghia_re}: the "
                      f"profiles would be compared with the wrong table; change one of them to match the other")

    @property
    def re(self) -> float:
        """Reynolds number rho U_lid L / eta with L = 1."""
        return self.material.rho_ref * self.lid_velocity / self.material.eta

    @property
    def dx(self) -> tuple[float, ...]:
        """The spacings of the figures, coarsest first (each run once)."""
        return tuple(sorted({float(v) for v in self.figures.values()}, reverse=True))

    def method(self, name: str) -> Method:
        return next(m for m in self.methods if m.name == name)

    def effects(self, m: Method, where: str = "") -> sph.Effects:
        return from_mapping(sph.Effects, merge({"walls": "no_slip"}, m.effects), f"{where or m.name}.effects")

    def numerics_of(self, m: Method, where: str = "") -> sph.Numerics:
        return from_mapping(sph.Numerics, merge(to_mapping(self.numerics), m.numerics), f"{where or m.name}.numerics")


@dataclass(frozen=True)
class Run:
    """One method at one spacing: everything its trajectory depends on (its cache key with the code);
    `groups` (the figures that show it) and `settings` (the analysis's) stay out of the key."""

    name: str
    case: str
    method: str
    effects: sph.Effects
    numerics: sph.Numerics
    dx: float
    material: sph.Material
    lid_velocity: float
    wall_layers: int
    lid_corners: str
    t_end: float
    frames: int
    keep: tuple[str, ...]
    connectivity_radius_factor: float
    groups: tuple[str, ...] = field(default=(), metadata={"key": False})
    settings: Settings = field(default=None, metadata={"key": False})

    @property
    def re(self) -> float:
        return self.material.rho_ref * self.lid_velocity / self.material.eta


def runs(s: Settings) -> list:
    """Every (dx, method), coarsest dx first, methods in config order."""
    return [Run(f"{m.name}_{dx_tag(dx)}", s.case, m.name, s.effects(m), s.numerics_of(m), dx, s.material,
                s.lid_velocity, s.wall_layers, s.lid_corners, s.t_end, s.frames, s.keep, s.connectivity_radius_factor,
                tuple(f for f, d in s.figures.items() if abs(float(d) - dx) < 1e-12), s)
            for dx in s.dx for m in s.methods]


def preflight(runs) -> None:
    """Every run about to start against the available memory, before anything is built."""
    for r in runs:
        check_fits(f"ldc2d {r.method} at dx = {r.dx:g}", (round(1.0 / r.dx) + 2 * r.wall_layers) ** 2, 2, r.dx,
                   r.numerics)


def scene(run: Run):
    return ldc.scene(run.dx, run.material, run.effects, layers=run.wall_layers, lid_velocity=run.lid_velocity,
                     lid_corners=run.lid_corners), run.numerics


def run_options(run: Run) -> dict:
    return {"case": run.case, "keep": run.keep, "connectivity_radius_factor": run.connectivity_radius_factor,
            "u_limit": run.numerics.c_ref_factor * run.material.u_ref,
            "metadata": {"re": run.re, "lid_velocity": run.lid_velocity, "wall_layers": run.wall_layers,
                         "lid_corners": run.lid_corners, "cavity_offset": ldc.offset(run.dx, run.wall_layers)}}
