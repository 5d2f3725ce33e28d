"""2D reverse Poiseuille flow (RPF): JAX-SPH's `cases/rpf.py` and LagrangeBench's RPF 2D dataset
(Toshev et al. 2024, Sec. 5 / App. B; Fatehi & Manzari 2011).

Box [0, 1) x [0, 2), periodic in both directions, fluid everywhere. The flow is driven by a body
force along x that changes sign at y = 1: g_x = +g for y < 1 and -g for y >= 1 (per particle,
`sph.forces.ReversePoiseuilleForce`). Starting from rest, each half develops a Poiseuille profile
of opposite sign; the steady state on y in [0, 1) is

    u(y) = g / (2 nu) y (1 - y),       u(y) = -u(y - 1) on [1, 2),       u_max = g / (8 nu).

The start-up (`u_startup`): the forcing is a square wave of period 2 in y,
f(y) = (4 g / pi) sum_{k odd} sin(k pi y) / k, and u_t = nu u_yy + f decouples into modes,

    u(y, t) = sum_{k odd} 4 g / (nu pi^3 k^3) (1 - exp(-nu k^2 pi^2 t)) sin(k pi y),

which tends to the steady profile above (its sine series) and relaxes with time scale 1/(nu pi^2).
"""
import numpy as np

from ..config import Effects, Material
from ..domain import Domain
from ..forces import ReversePoiseuilleForce
from ..lattice import cartesian
from ..scene import Scene
from ..state import FLUID

BOX = (1.0, 2.0)
SPLIT = 1.0


def force(g: float = 1.0) -> ReversePoiseuilleForce:
    """g_x = +g below y = 1, -g above, evaluated per particle."""
    return ReversePoiseuilleForce(g=float(g), split=SPLIT, axis=0, split_axis=1)


def u_steady(y, g: float, nu: float) -> np.ndarray:
    """Steady x-velocity at heights y (any shape), periodic with period 2."""
    y = np.mod(np.asarray(y, dtype=float), 2.0)
    lower = y < SPLIT
    yy = np.where(lower, y, y - SPLIT)
    u = g / (2.0 * nu) * yy * (1.0 - yy)
    return np.where(lower, u, -u)


def u_startup(y, t, g: float, nu: float, n_modes: int = 200) -> np.ndarray:
    """x-velocity at heights y (M,) and times t (scalar or (T,)) from rest: shape (T, M) or (M,)."""
    y = np.asarray(y, dtype=float)
    t_arr = np.atleast_1d(np.asarray(t, dtype=float))
    k = 2 * np.arange(n_modes) + 1.0
    amp = 4.0 * g / (nu * np.pi**3 * k**3)
    growth = 1.0 - np.exp(-nu * (k * np.pi) ** 2 * t_arr[:, None])          # (T, K)
    modes = np.sin(np.pi * k[:, None] * y[None, :])                          # (K, M)
    u = (growth * amp[None, :]) @ modes
    return u if np.ndim(t) else u[0]


def u_max_steady(g: float, nu: float) -> float:
    return g / (8.0 * nu)


def scene(dx: float, material: Material, effects: Effects = Effects(), r=None, g: float = 1.0,
          name: str = "rpf2d") -> Scene:
    """RPF scene at rest; `r` overrides the cell-centred lattice (e.g. relaxed positions).
    `effects` must not declare gravity: the scene carries the per-particle RPF body force."""
    if r is None:
        r = cartesian([0.0, 0.0], list(BOX), dx)
    r = np.asarray(r, dtype=float)
    return Scene(name=name, dx=dx, domain=Domain(box=BOX, periodic=(True, True)), material=material,
                 effects=effects, r=r, u=np.zeros_like(r), tag=np.full(len(r), FLUID, np.int32),
                 body_force=force(g) if g else None)
