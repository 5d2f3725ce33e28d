"""Frozen, validated configuration of the material, the numerics and the declared effects.

Every field is checked on construction, named in the error (`material.eta: ...`): every number must
be finite, and each has its sign or range (see the class docstrings).
"""
from dataclasses import dataclass, fields
from typing import Optional

from .errors import require, require_finite
from .kernels import KERNELS
from .precision import DTYPES

WALL_MODES = (None, "no_slip", "free_slip")
NEIGHBOR_SEARCHES = ("cell_sort", "jax_md")


@dataclass(frozen=True)
class Material:
    """A weakly compressible fluid.

    rho_ref  reference density
    eta      dynamic viscosity eta = rho nu
    u_ref    reference (maximum expected) velocity; sets the artificial sound speed c_ref
    kappa    thermal conductivity (needed by effects.heat)
    c_p      specific heat capacity (needed by effects.heat)
    """

    rho_ref: float = 1.0
    eta: float = 0.01
    u_ref: float = 1.0
    kappa: Optional[float] = None
    c_p: Optional[float] = None

    def __post_init__(self):
        require_finite(self, "material")
        require(self.rho_ref > 0, "material.rho_ref", f"must be positive, got {self.rho_ref}")
        require(self.eta >= 0, "material.eta", f"must be >= 0 (0 = inviscid), got {self.eta}")
        require(self.u_ref > 0, "material.u_ref", f"must be positive, got {self.u_ref}")
        require(self.kappa is None or self.kappa > 0, "material.kappa", f"must be positive, got {self.kappa}")
        require(self.c_p is None or self.c_p > 0, "material.c_p", f"must be positive, got {self.c_p}")


@dataclass(frozen=True)
class Effects:
    """The physics a scene declares. The step is assembled from exactly these.

    tvf                   transport-velocity formulation (Adami 2013)
    riemann               Riemann SPH with dissipation limiter (Zhang 2017b); needs density_evolution
    density_evolution     continuity equation instead of density summation
    density_reinit_every  Shepard density re-initialization every N steps (0 = off); needs evolution
    gravity               constant body force vector, or null for none (a scene may instead carry a
                          space-dependent `body_force`, see sph.forces)
    walls                 generalized wall boundary condition (Adami 2012; one-sided Riemann walls
                          with Riemann SPH): "no_slip" or "free_slip", null = no walls
    artificial_viscosity  alpha of Monaghan's artificial viscosity (0 = off), for free-surface flows
    heat                  thermal diffusion (Cleary 1998); needs material.kappa, material.c_p and an
                          initial temperature in the scene
    surface_tension       sigma of the continuum surface force between phases 0 and 1 (Morris 2000,
                          sph.surface_tension), 0 = off; needs scene.phase
    """

    tvf: bool = False
    riemann: bool = False
    density_evolution: bool = False
    density_reinit_every: int = 0
    gravity: Optional[tuple[float, ...]] = None
    walls: Optional[str] = None
    heat: bool = False
    artificial_viscosity: float = 0.0
    surface_tension: float = 0.0

    def __post_init__(self):
        require_finite(self, "effects")
        require(self.surface_tension >= 0, "effects.surface_tension", f"must be >= 0, got {self.surface_tension}")
        require(self.walls in WALL_MODES, "effects.walls",
                f"{self.walls!r} is not one of {WALL_MODES} (null = no walls)")
        require(not (self.riemann and not self.density_evolution), "effects.riemann",
                "Riemann SPH evolves density with the Riemann velocity (Zhang 2017b, eq. 8): "
                "set effects.density_evolution: true")
        require(not (self.riemann and self.tvf), "effects.tvf",
                "the transport-velocity formulation is not combined with Riemann SPH here; choose one")
        require(self.artificial_viscosity >= 0, "effects.artificial_viscosity",
                f"must be >= 0, got {self.artificial_viscosity}")
        require(self.density_reinit_every >= 0, "effects.density_reinit_every",
                f"must be >= 0, got {self.density_reinit_every}")
        require(not (self.density_reinit_every and not self.density_evolution),
                "effects.density_reinit_every",
                "re-initialization corrects an evolved density: set effects.density_evolution: true")

    def names(self) -> list[str]:
        """Names of the declared effects (fields off their default), in field order, for logs and
        metadata: a flag by its name, a vector (gravity) by its name, any other value as name=value."""
        out = []
        for f in fields(self):
            value = getattr(self, f.name)
            if value == f.default:
                continue
            out.append(f.name if isinstance(value, (bool, tuple, list)) else f"{f.name}={value}")
        return out


@dataclass(frozen=True)
class Numerics:
    """Discretization choices.

    kernel, h_factor       kernel name and h = h_factor * dx
    cfl                    factor of the convective, viscous and body-force time-step limits
    c_ref_factor           c_ref = c_ref_factor * u_ref (weak compressibility, Ma ~ 0.1)
    gamma                  Tait exponent
    p_bg_factor            background pressure in the EoS, p_bg = p_bg_factor * p_ref
    p_b_factor             TVF background pressure, p_b = p_b_factor * p_ref (Adami 2013)
    eta_limiter            Riemann dissipation limiter eta (Zhang 2017b eq. 11); negative = off (finite)
    dt                     fixed time step instead of the CFL one (null = from the limits); one above the
                           limits is reported by build_solver (a `sph.solver.UnstableTimeStep` warning)
    dtype                  float64 or float32
    skin_factor            neighbour-list skin = skin_factor * dx; lists rebuild after skin/2 motion
    capacity_multiplier    neighbour slots allocated per particle relative to the current maximum
    neighbor_search        "cell_sort" (default: the sort-based cell list built for this solver,
                           sph.cell_list; the same pairs as jax-md's, faster in 2D and 3D) or
                           "jax_md" (jax-md's cell list, the reference implementation)
    reorder_every          sort the fluid particles by cell every that many steps (at the next frame of
                           `sph.simulate.run`; sph.reorder), so that neighbours stay close in memory as
                           the flow mixes them; 0 = keep the scene's order. Outputs keep the scene's order.
    """

    kernel: str = "quintic"
    h_factor: float = 1.0
    cfl: float = 0.25
    c_ref_factor: float = 10.0
    gamma: float = 1.0
    p_bg_factor: float = 0.0
    p_b_factor: float = 1.0
    eta_limiter: float = 3.0
    dt: Optional[float] = None
    dtype: str = "float64"
    skin_factor: float = 0.5
    capacity_multiplier: float = 1.25
    neighbor_search: str = "cell_sort"
    reorder_every: int = 0

    def __post_init__(self):
        require_finite(self, "numerics")
        require(self.kernel in KERNELS, "numerics.kernel", f"{self.kernel!r} is not one of {sorted(KERNELS)}")
        require(self.dtype in DTYPES, "numerics.dtype", f"{self.dtype!r} is not one of {sorted(DTYPES)}")
        require(self.h_factor > 0, "numerics.h_factor", f"must be positive, got {self.h_factor}")
        require(0 < self.cfl <= 1, "numerics.cfl", f"must be in (0, 1], got {self.cfl}")
        require(self.c_ref_factor > 0, "numerics.c_ref_factor", f"must be positive, got {self.c_ref_factor}")
        require(self.gamma > 0, "numerics.gamma", f"must be positive, got {self.gamma}")
        require(self.p_bg_factor >= 0, "numerics.p_bg_factor", f"must be >= 0, got {self.p_bg_factor}")
        require(self.p_b_factor >= 0, "numerics.p_b_factor", f"must be >= 0 (0 = no TVF background pressure), "
                f"got {self.p_b_factor}")
        require(self.dt is None or self.dt > 0, "numerics.dt", f"must be positive or null, got {self.dt}")
        require(self.skin_factor >= 0, "numerics.skin_factor", f"must be >= 0, got {self.skin_factor}")
        require(self.neighbor_search in NEIGHBOR_SEARCHES, "numerics.neighbor_search",
                f"{self.neighbor_search!r} is not one of {list(NEIGHBOR_SEARCHES)}")
        require(isinstance(self.reorder_every, int) and self.reorder_every >= 0, "numerics.reorder_every",
                f"must be a whole number of steps >= 0 (0 = never), got {self.reorder_every!r}")
        require(self.capacity_multiplier >= 1, "numerics.capacity_multiplier",
                f"must be >= 1, got {self.capacity_multiplier}")
