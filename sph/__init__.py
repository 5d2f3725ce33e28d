"""sph: a thin, differentiable weakly compressible SPH core in JAX (reproduction of JAX-SPH).

Import order matters for precision: `sph.precision` switches x64 on before any array exists.
"""
from . import precision  # noqa: F401  (enables x64 first)
from .config import Effects, Material, Numerics
from .configtools import ConfigError
from .domain import Domain
from .scene import Scene
from .solver import Solver, build_solver
from .state import FLUID, MOVING_WALL, WALL, ParticleState

__all__ = ["Effects", "Material", "Numerics", "ConfigError", "Domain", "Scene", "Solver", "build_solver",
           "ParticleState", "FLUID", "WALL", "MOVING_WALL"]
