"""A scene: geometry (particles and domain), material and the effects it declares.

A scene is checked on construction against the effects it declares, so that a scene asking for an
effect without what that effect needs fails at load with a message naming the missing piece.
"""
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .config import Effects, Material
from .errors import ConfigError
from .domain import Domain
from .state import FLUID, MOVING_WALL, WALL


@dataclass(frozen=True, eq=False)
class Scene:
    """Initial particles in a `domain`, plus what to simulate.

    r, u, tag   (N, dim), (N, dim), (N,): positions, velocities, tags (FLUID, WALL, MOVING_WALL);
                the velocity of a wall particle is its prescribed wall velocity
    normal      (N, dim) unit wall normals pointing into the fluid (rows of fluid particles unused);
                needed by Riemann walls and free-slip walls
    T           (N,) initial temperature (effects.heat)
    T_fixed     (N,) bool, particles whose temperature is held at T (Dirichlet segments)
    body_force  a space-dependent body force (sph.forces), instead of effects.gravity
    T_zones     tuple of sph.heat.TemperatureZone (inflow / outflow slabs of the temperature)
    mass        (N,) particle masses; None: rho_ref dx^dim for every particle (`particle_mass`)
    phase       (N,) int phase (material index) of every particle, for effects between phases (e.g.
                surface tension); None: one phase, 0
    """

    name: str
    dx: float
    domain: Domain
    material: Material
    effects: Effects
    r: np.ndarray
    u: np.ndarray
    tag: np.ndarray
    normal: Optional[np.ndarray] = None
    T: Optional[np.ndarray] = None
    T_fixed: Optional[np.ndarray] = None
    body_force: Optional[object] = None
    T_zones: tuple = ()
    mass: Optional[np.ndarray] = None
    phase: Optional[np.ndarray] = None

    def __post_init__(self):
        if not (isinstance(self.dx, (int, float, np.floating)) and math.isfinite(self.dx) and self.dx > 0):
            raise ConfigError(f"scene {self.name}: dx must be a positive number, got {self.dx!r}")
        n, dim = self.r.shape
        if dim != self.domain.dim:
            raise ConfigError(f"scene {self.name}: positions are {dim}D but the domain is {self.domain.dim}D")
        if self.u.shape != (n, dim) or self.tag.shape != (n,):
            raise ConfigError(f"scene {self.name}: u {self.u.shape} and tag {self.tag.shape} must match r {(n, dim)}")
        if not np.all(np.isfinite(self.r)) or not np.all(np.isfinite(self.u)):
            raise ConfigError(f"scene {self.name}: initial positions or velocities are not finite")
        box = np.array(self.domain.box)
        outside = np.any((self.r < 0) | (self.r >= box), axis=1)
        if outside.any():
            i = int(np.argmax(outside))
            raise ConfigError(f"scene {self.name}: particle {i} at {self.r[i]} lies outside the box [0, {box})")
        unknown = ~np.isin(self.tag, (FLUID, WALL, MOVING_WALL))
        if unknown.any():
            raise ConfigError(f"scene {self.name}: particle {int(np.argmax(unknown))} has unknown tag "
                              f"{self.tag[unknown][0]} (use FLUID=0, WALL=1, MOVING_WALL=2)")
        if not np.any(self.tag == FLUID):
            raise ConfigError(f"scene {self.name}: no fluid particles")
        self._check_walls()
        self._check_heat()
        if self.mass is not None and (np.shape(self.mass) != (n,) or not np.all(np.isfinite(self.mass))
                                      or np.any(np.asarray(self.mass) <= 0)):
            raise ConfigError(f"scene {self.name}: mass must be ({n},) positive finite values, got shape "
                              f"{np.shape(self.mass)}")
        if self.phase is not None and (np.shape(self.phase) != (n,) or not np.issubdtype(np.asarray(self.phase).dtype,
                                                                                          np.integer)):
            raise ConfigError(f"scene {self.name}: phase must be ({n},) integers, got {np.asarray(self.phase).dtype} "
                              f"of shape {np.shape(self.phase)}")
        if self.body_force is not None and self.effects.gravity is not None:
            raise ConfigError(f"scene {self.name}: declares both effects.gravity and a body_force; keep one")

    def _check_walls(self):
        fx, wall = self.effects, self.wall_mask
        where = f"scene {self.name}"
        if fx.walls is None:
            if wall.any():
                raise ConfigError(f"{where}: has {int(wall.sum())} wall particles but effects.walls is null; "
                                  "declare effects.walls: no_slip or free_slip")
            return
        if not wall.any():
            raise ConfigError(f"{where}: effects.walls is {fx.walls!r} but the scene has no wall particles "
                              "(tag WALL=1 or MOVING_WALL=2)")
        fixed = self.tag == WALL
        if np.any(self.u[fixed] != 0):
            raise ConfigError(f"{where}: fixed wall particles (tag WALL) must have zero velocity; "
                              "tag a wall with a prescribed velocity MOVING_WALL")
        moving = self.tag == MOVING_WALL
        if moving.any() and np.all(self.u[moving] == 0):
            raise ConfigError(f"{where}: moving-wall particles (tag MOVING_WALL) have no velocity; "
                              "set their prescribed velocity in scene.u")
        needs = [why for why, on in (("Riemann walls (effects.riemann)", fx.riemann),
                                     ("free-slip walls (effects.walls: free_slip)", fx.walls == "free_slip"))
                 if on]
        if needs and self.normal is None:
            raise ConfigError(f"{where}: {' and '.join(needs)} need wall normals: scene.normal is missing")
        if self.normal is not None:
            if self.normal.shape != self.r.shape:
                raise ConfigError(f"{where}: normal {self.normal.shape} must match r {self.r.shape}")
            length = np.linalg.norm(self.normal[wall], axis=1)
            bad = ~np.isclose(length, 1.0, atol=1e-6)
            if bad.any():
                i = int(np.flatnonzero(wall)[np.argmax(bad)])
                raise ConfigError(f"{where}: scene.normal of wall particle {i} is {self.normal[i]}, not a unit vector")

    def _check_heat(self):
        fx, mat = self.effects, self.material
        where = f"scene {self.name}"
        if not fx.heat:
            if self.T is not None or self.T_fixed is not None or self.T_zones:
                raise ConfigError(f"{where}: carries a temperature but effects.heat is false")
            return
        for key in ("kappa", "c_p"):
            if getattr(mat, key) is None:
                raise ConfigError(f"{where}: effects.heat needs material.{key}")
        if self.T is None:
            raise ConfigError(f"{where}: effects.heat needs an initial temperature scene.T")
        if self.T.shape != (self.n,):
            raise ConfigError(f"{where}: T {self.T.shape} must have one value per particle ({self.n},)")
        if self.T_fixed is not None:
            if self.T_fixed.shape != (self.n,):
                raise ConfigError(f"{where}: T_fixed {self.T_fixed.shape} must have shape ({self.n},)")
            missing = self.T_fixed & ~np.isfinite(self.T)
            if missing.any():
                raise ConfigError(f"{where}: Dirichlet (T_fixed) particle {int(np.argmax(missing))} has no "
                                  "temperature: set scene.T there")
        free = ~self.T_fixed if self.T_fixed is not None else np.ones(self.n, bool)
        nonfinite = free & (self.tag == FLUID) & ~np.isfinite(self.T)
        if nonfinite.any():
            raise ConfigError(f"{where}: scene.T of fluid particle {int(np.argmax(nonfinite))} is not finite")

    @property
    def dim(self) -> int:
        return self.domain.dim

    @property
    def n(self) -> int:
        return self.r.shape[0]

    @property
    def particle_mass(self) -> np.ndarray:
        """(N,) masses: `mass`, or rho_ref dx^dim (the lattice's volume times the reference density)."""
        if self.mass is not None:
            return np.asarray(self.mass, float)
        return np.full(self.n, self.material.rho_ref * self.dx**self.dim)

    @property
    def phases(self) -> np.ndarray:
        """(N,) int phases (`phase`, or 0 everywhere)."""
        return np.asarray(self.phase) if self.phase is not None else np.zeros(self.n, np.int32)

    @property
    def wall_mask(self) -> np.ndarray:
        return np.isin(self.tag, (WALL, MOVING_WALL))

    @property
    def fluid_mask(self) -> np.ndarray:
        return self.tag == FLUID
