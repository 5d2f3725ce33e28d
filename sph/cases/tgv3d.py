"""3D Taylor-Green vortex in the periodic box (2 pi)^3 (JAX-SPH, Toshev et al. 2024, App. A.4, Fig. 9).

u = U sin x cos y cos z,  v = -U cos x sin y cos z,  w = 0  at t = 0 (L = 1, so Re = U / nu).
No closed-form decay: the vortex stretches, transitions and dissipates; the reference is a
grid solution (JAX-Fluids, validation_refs/tgv3d_ref_<Re>.txt). At t = 0 the field is exact:

  E_kin / V = <|u|^2> / 2 = U^2 / 8                       (each of <sin^2 cos^2 cos^2> = 1/8)
  -dE/dt    = nu <|grad u|^2> = nu <|omega|^2> = 3 nu U^2 / 4
              (9 derivative components of u and v, six of them nonzero, each with mean square 1/8;
               for an incompressible periodic field <|grad u|^2> = <|omega|^2>)

E_kin here is (1/2) sum_i m_i |v_i|^2 / (rho_ref (2 pi)^3), i.e. per unit volume and density,
the normalisation of the reference file.
"""
import math

import numpy as np

from ..config import Effects, Material
from ..errors import ConfigError
from ..domain import Domain
from ..lattice import cartesian, check_run_size, count
from ..scene import Scene
from ..state import FLUID

SIDE = 2.0 * np.pi
"""Side of the periodic box."""


def velocity(r, U: float = 1.0) -> np.ndarray:
    x, y, z = r[:, 0], r[:, 1], r[:, 2]
    cz = np.cos(z)
    return np.stack([U * np.sin(x) * np.cos(y) * cz, -U * np.cos(x) * np.sin(y) * cz, np.zeros_like(x)], axis=1)


def e_kin_initial(U: float = 1.0) -> float:
    """Exact kinetic energy per unit volume and density at t = 0: U^2 / 8."""
    return U**2 / 8.0


def dissipation_initial(nu: float, U: float = 1.0) -> float:
    """Exact -dE/dt per unit volume and density at t = 0: nu <|grad u|^2> = 3 nu U^2 / 4."""
    return 0.75 * nu * U**2


def n_side(dx: float) -> int:
    """Particles per side for spacing `dx`; the box must hold a whole number of them."""
    n = SIDE / dx
    if not (math.isfinite(n) and n >= 1 and abs(n - round(n)) < 1e-6 * n):
        raise ConfigError(f"scene tgv3d: dx = {dx:g} does not divide the box side 2 pi into whole cells "
                          f"(2 pi / dx = {n:.6g}); use dx = 2 pi / n")
    return int(round(n))


def dx_for(n: int) -> float:
    """The spacing of n particles per side."""
    return SIDE / n


def scene(dx: float, material: Material, effects: Effects, r=None, name: str = "tgv3d") -> Scene:
    """TGV scene in the periodic box (2 pi)^3 on the cell-centred lattice of spacing dx (2 pi / dx
    particles per side); `r` overrides the positions (e.g. relaxed ones)."""
    n = n_side(dx)
    if r is None:
        check_run_size(count([0.0] * 3, [SIDE] * 3, dx), dx, f"scene {name}")
        r = cartesian([0.0] * 3, [SIDE] * 3, dx)
    r = np.asarray(r, dtype=float)
    if r.shape != (n**3, 3):
        raise ConfigError(f"scene {name}: positions {r.shape} do not match {n}^3 particles at dx = {dx:g}")
    return Scene(name=name, dx=dx, domain=Domain(box=(SIDE,) * 3, periodic=(True,) * 3), material=material,
                 effects=effects, r=r, u=velocity(r, material.u_ref), tag=np.full(len(r), FLUID, np.int32))
