"""A 2D circular droplet at rest in a periodic box of another fluid of the same density: the Laplace
test of surface tension (Morris 2000, Sec. 5; Adami, Hu & Adams 2010, Sec. 4.1).

Box [0, L]^2, periodic, square lattice of spacing dx; phase 1 on the particles within radius R of the
centre, phase 0 outside. At rest the pressure inside exceeds the pressure outside by sigma / R
(Laplace's law in 2D, curvature 1 / R); `laplace_jump` measures it away from the interface
(`margin` kernel supports), and the velocities that remain are the spurious currents of the
discretization.

Recipe (`METHOD`, `NUMERICS`): standard SPH with summation density and JAX-SPH's EoS background
pressure 0.01 p_ref (against the tensile instability where the pressure oscillates below zero);
u_ref = 2 sqrt(sigma / (rho R)) makes c_ref = 10 u_ref large enough that the Laplace pressure
compresses the droplet by about 1 %. The transport-velocity formulation is not the recipe: at dx
0.02 to t = 0.5 its jump oscillated about half of sigma / R (likely its background pressure resisting
the compression the jump needs; not run longer, not tested further). The pressure reaches the jump
by viscous settling, t ~ R^2 rho / eta.
"""
import numpy as np

from ..config import Effects, Material, Numerics
from ..domain import Domain
from ..errors import ConfigError
from ..lattice import cartesian
from ..scene import Scene
from ..state import FLUID

METHOD = "sph"
NUMERICS = Numerics(kernel="quintic", h_factor=1.0, cfl=0.25, c_ref_factor=10.0, p_bg_factor=0.01, dtype="float64")


def u_ref(sigma: float, radius: float, rho_ref: float = 1.0) -> float:
    """Velocity scale of the capillary pressure sigma / R: 2 sqrt(sigma / (rho R))."""
    return 2.0 * float(np.sqrt(sigma / (rho_ref * radius)))


def effects(sigma: float) -> Effects:
    return Effects(surface_tension=sigma)


def scene(dx: float, sigma: float, radius: float = 0.25, box: float = 1.0, eta: float = 0.05,
          rho_ref: float = 1.0, name: str = "droplet") -> Scene:
    """The droplet of radius `radius` at the centre of the periodic box [0, box]^2."""
    n = box / dx
    if abs(n - round(n)) > 1e-6:
        raise ConfigError(f"dx: the droplet's box {box:g} is not a whole number of spacings dx = {dx:g}; use dx = "
                          f"{box / round(n):.12g} ({round(n)} spacings)")
    r = cartesian([0.0, 0.0], [box, box], dx)
    inside = np.linalg.norm(r - 0.5 * box, axis=1) < radius
    mat = Material(rho_ref=rho_ref, eta=eta, u_ref=u_ref(sigma, radius, rho_ref))
    return Scene(name=name, dx=dx, domain=Domain(box=(box, box), periodic=(True, True)), material=mat,
                 effects=effects(sigma), r=r, u=np.zeros_like(r), tag=np.full(len(r), FLUID, np.int32),
                 phase=inside.astype(np.int32))


def laplace_jump(r, p, centre, radius: float, width: float) -> tuple:
    """(mean p inside r < R - width, mean p outside r > R + width): the two sides of the interface."""
    d = np.linalg.norm(np.asarray(r) - np.asarray(centre), axis=1)
    p = np.asarray(p)
    return float(p[d < radius - width].mean()), float(p[d > radius + width].mean())
