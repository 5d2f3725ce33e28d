"""2D Taylor-Green vortex in the periodic unit square (Adami, Hu & Adams 2013, Sec. 4.1).

u = -U cos(2 pi x) sin(2 pi y),  v = U sin(2 pi x) cos(2 pi y)  at t = 0, decaying as
u_max(t) = U exp(-8 pi^2 t / Re),  E_kin(t) / (rho U^2 L^2) = 0.25 exp(-16 pi^2 t / Re),  Re = U L / nu.
E_kin here is (1/2) sum_i m_i |u_i|^2 per unit domain area.
"""
import numpy as np

from ..config import Effects, Material
from ..domain import Domain
from ..lattice import cartesian, check_run_size, count
from ..scene import Scene
from ..state import FLUID


def velocity(r, U: float = 1.0) -> np.ndarray:
    x, y = r[:, 0], r[:, 1]
    return np.stack([-U * np.cos(2 * np.pi * x) * np.sin(2 * np.pi * y),
                     U * np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)], axis=1)


def u_max_exact(t, re: float):
    return np.exp(-8.0 * np.pi**2 * np.asarray(t) / re)


def e_kin_exact(t, re: float):
    return 0.25 * np.exp(-16.0 * np.pi**2 * np.asarray(t) / re)


def scene(dx: float, material: Material, effects: Effects, r=None, name: str = "tgv2d") -> Scene:
    """TGV scene on the unit square; `r` overrides the lattice (e.g. relaxed positions)."""
    if r is None:
        check_run_size(count([0.0, 0.0], [1.0, 1.0], dx), dx, f"scene {name}")
        r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
    r = np.asarray(r, dtype=float)
    return Scene(name=name, dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)), material=material,
                 effects=effects, r=r, u=velocity(r, material.u_ref), tag=np.full(len(r), FLUID, np.int32))
