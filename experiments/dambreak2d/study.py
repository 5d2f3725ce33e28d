"""The 2D dam break (Colagrossi & Landrini 2003; JAX-SPH Fig. 8; the protocol is lab.experiment's):
one run per water column of the profile (`<column>_dx<dx>`), Riemann SPH in a closed tank, started
hydrostatic (`initial_state`), a frame every `frame_dt`. What a run builds and what its numbers
depend on lives here; what it measures against the experiments (the wall-pressure sensor, the surge
front) is analysis.py, whose edits re-evaluate the runs without re-running them.
"""
import math
from dataclasses import dataclass, field

import sph
from sph.cases import tank
from lab.configtools import require, require_agree, require_finite, to_mapping
from lab.layout import dx_tag

KEEPABLE = ("velocity", "density", "pressure")


@dataclass(frozen=True)
class Tank:
    """Closed rectangular tank: interior [0, length] x [0, height], `layers` wall layers per side."""

    length: float = 5.366
    height: float = 2.0
    layers: int = 3

    def __post_init__(self):
        require_finite(self, "tank")
        require(self.length > 0, "tank.length", f"must be positive, got {self.length}")
        require(self.height > 0, "tank.height", f"must be positive, got {self.height}")
        require(self.layers >= 1, "tank.layers", f"must be >= 1, got {self.layers}")


@dataclass(frozen=True)
class Column:
    """One water column against the left wall: width x height, run to t_end (simulation time; with
    g = H = 1 this is t sqrt(g/H))."""

    name: str
    width: float
    height: float
    t_end: float

    def __post_init__(self):
        require_finite(self)
        require(self.width > 0, "width", f"must be positive, got {self.width}")
        require(self.height > 0, "height", f"must be positive, got {self.height}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")


@dataclass(frozen=True)
class Fluid:
    """Water: reference density and dynamic viscosity. u_ref = sqrt(2 g H) follows from the column."""

    rho_ref: float = 1.0
    eta: float = 5.0e-5

    def __post_init__(self):
        require_finite(self, "fluid")
        require(self.rho_ref > 0, "fluid.rho_ref", f"must be positive, got {self.rho_ref}")
        require(self.eta >= 0, "fluid.eta", f"must be >= 0, got {self.eta}")


@dataclass(frozen=True)
class Settings:
    """One profile of the experiment (see config.yaml for the meaning of each key)."""

    columns: tuple[Column, ...]
    dx: float
    case: str = "dambreak2d"
    tank: Tank = field(default_factory=Tank)
    fluid: Fluid = field(default_factory=Fluid)
    effects: sph.Effects = field(default_factory=sph.Effects)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    hydrostatic_init: bool = True
    frame_dt: float = 0.02
    keep: tuple[str, ...] = ("density", "pressure")
    pressure_column: str = "tall"
    front_column: str = "square"
    sensor_height: float = 0.2
    wet_threshold: float = 0.1
    height_band: float = 0.1
    front_t_max: float = 2.5
    peak_threshold: float = 0.1
    peak_window: float = 1.0
    smooth_window: float = 0.1
    snapshot_times: tuple[float, ...] = (1.62, 2.38, 4.0, 5.21, 6.02, 7.23)
    pressure_range: tuple[float, ...] = (0.0, 1.0)
    connectivity_radius_factor: float = 1.45

    def __post_init__(self):
        require_finite(self)
        require(self.dx > 0, "dx", f"must be positive, got {self.dx}")
        require(len(self.columns) > 0, "columns", "needs at least one column")
        names = [c.name for c in self.columns]
        for i, n in enumerate(names):
            require(names.index(n) == i, f"columns[{i}].name", f"{n!r} appears twice")
        for i, c in enumerate(self.columns):
            require(c.width < self.tank.length and c.height < self.tank.height, f"columns[{i}]",
                    f"{c.width} x {c.height} does not fit into the tank {self.tank.length} x {self.tank.height}")
            for key, size in (("width", c.width), ("height", c.height)):
                n = size / self.dx
                require_agree(abs(n - round(n)) < 1e-6, (f"columns[{i}].{key}", "dx"),
                              f"{size} is not a whole number of particle spacings dx = {self.dx}")
        require(self.dx > 0, "dx", f"must be positive, got {self.dx}")
        fx = self.effects
        require(fx.gravity is not None and len(fx.gravity) == 2 and fx.gravity[0] == 0 and fx.gravity[1] < 0,
                "effects.gravity", f"the dam break needs gravity [0, -g] with g > 0, got {fx.gravity}")
        require(fx.walls is not None, "effects.walls", "the tank needs walls: no_slip or free_slip")
        require(not fx.heat, "effects.heat",
                "the dam break carries no temperature: this config's `fluid` section has only rho_ref and eta "
                "(no kappa or c_p) and the tank no thermal boundary; set effects.heat: false "
                "(heat transfer is the thermal experiment, experiments/thermal)")
        require(self.connectivity_radius_factor > 0, "connectivity_radius_factor",
                f"must be positive, got {self.connectivity_radius_factor}")
        require(self.frame_dt > 0, "frame_dt", f"must be positive, got {self.frame_dt}")
        for i, k in enumerate(self.keep):
            require(k in KEEPABLE, f"keep[{i}]", f"{k!r} is not one of {list(KEEPABLE)}")
        require("pressure" in self.keep, "keep", "must contain 'pressure' (wall sensor and Fig. 8)")
        require(self.pressure_column in names, "pressure_column", f"{self.pressure_column!r} is not one of {names}")
        require(self.front_column in names, "front_column", f"{self.front_column!r} is not one of {names}")
        require(0 < self.sensor_height < self.tank.height, "sensor_height",
                f"must lie inside the tank height, got {self.sensor_height}")
        require(self.wet_threshold > 0, "wet_threshold", f"must be positive, got {self.wet_threshold}")
        require(self.height_band > 0, "height_band", f"must be positive, got {self.height_band}")
        require(self.peak_window > 0, "peak_window", f"must be positive, got {self.peak_window}")
        require(self.smooth_window >= 0, "smooth_window", f"must be >= 0, got {self.smooth_window}")
        require(len(self.pressure_range) == 2, "pressure_range",
                f"expected [min, max], got {list(self.pressure_range)}")
        lo, hi = self.pressure_range
        require(hi > lo, "pressure_range", f"needs min < max, got {list(self.pressure_range)}")

    @property
    def g(self) -> float:
        return -float(self.effects.gravity[1])

    def column(self, name: str) -> Column:
        return next(c for c in self.columns if c.name == name)

    def material(self, column: Column) -> sph.Material:
        """rho_ref, eta and u_ref = sqrt(2 g H) of the column."""
        return sph.Material(rho_ref=self.fluid.rho_ref, eta=self.fluid.eta,
                            u_ref=math.sqrt(2.0 * self.g * column.height))

    @property
    def offset(self) -> float:
        """Position of the tank's inner lower-left corner in the scene box (wall layers below/left)."""
        return self.tank.layers * self.dx


@dataclass(frozen=True)
class Run:
    """One column: everything its trajectory depends on (the simulation settings, not the evaluation
    keys: sensor, bands, figure; those come with `settings`, out of the key, so changing them only
    re-evaluates)."""

    name: str
    column: Column
    case: str
    dx: float
    tank: Tank
    fluid: Fluid
    effects: sph.Effects
    numerics: sph.Numerics
    hydrostatic_init: bool
    frame_dt: float
    keep: tuple[str, ...]
    settings: Settings = field(metadata={"key": False})

    @property
    def t_end(self) -> float:
        return self.column.t_end

    @property
    def method(self) -> str:
        """The record's method: the column's name (the atlas's rows)."""
        return self.column.name


def runs(s: Settings) -> list:
    return [Run(f"{c.name}_{dx_tag(s.dx)}", c, s.case, s.dx, s.tank, s.fluid, s.effects, s.numerics,
                s.hydrostatic_init, s.frame_dt, s.keep, s) for c in s.columns]


def scene(run: Run):
    s, c = run.settings, run.column
    sc = tank.scene(run.dx, s.material(c), run.effects, width=c.width, height=c.height, tank_length=run.tank.length,
                    tank_height=run.tank.height, layers=run.tank.layers, name=f"dambreak_{c.name}")
    return sc, run.numerics


def initial_state(run: Run, solver: sph.Solver):
    """(state, nbrs) at t = 0: the column at rest, with the hydrostatic pressure
    p = rho_ref g (H - y) and the density of the equation of state at that pressure when
    `hydrostatic_init` (otherwise rho = rho_ref, p = 0 and the column first settles under gravity,
    ringing with acoustic waves). The stored initial acceleration is that of the uniform state; it
    enters only the first step (an error of dt g in the velocity)."""
    s = run.settings
    state, nbrs = solver.init_fn()
    if not run.hydrostatic_init:
        return state, nbrs
    return tank.hydrostatic(state, solver.eos, run.fluid.rho_ref, s.g, s.offset + run.column.height), nbrs


def run_options(run: Run) -> dict:
    s = run.settings
    return {"case": run.case, "method": "riemann" if run.effects.riemann else "sph", "frame_dt": run.frame_dt,
            "keep": run.keep, "connectivity_radius_factor": s.connectivity_radius_factor,
            "u_limit": run.numerics.c_ref_factor * s.material(run.column).u_ref,
            "metadata": {"column": to_mapping(run.column), "tank": to_mapping(run.tank), "tank_offset": s.offset,
                         "g": s.g, "hydrostatic_init": run.hydrostatic_init}}
