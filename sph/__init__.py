"""sph: a thin, differentiable weakly compressible SPH core in JAX (reproduction of JAX-SPH).

`import sph` leaves JAX's x64 flag alone; a solver built with `numerics.dtype: float64` switches it
on (`sph.precision.enable_x64`), float32 runs never need it. Nor does it touch XLA_FLAGS: the entry
points set XLA's CPU defaults (`sph.xla_cpu.set_cpu_defaults()`, one call to opt in).

The physics core is the modules of this folder and `sph.cases`; `lab` (configs from YAML,
cached runs, files, the command line) builds on it and is never imported by it.
"""
from . import precision  # noqa: F401
from .config import Effects, Material, Numerics
from .errors import ConfigError
from .domain import Domain
from .scene import Scene
from .solver import Solver, build_solver
from .state import FLUID, MOVING_WALL, WALL, ParticleState
from .xla_cpu import set_cpu_defaults

__all__ = ["Effects", "Material", "Numerics", "ConfigError", "Domain", "Scene", "Solver", "build_solver",
           "ParticleState", "FLUID", "WALL", "MOVING_WALL", "set_cpu_defaults"]
