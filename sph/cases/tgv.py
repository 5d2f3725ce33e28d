"""2D Taylor-Green vortex in the periodic unit square (Adami, Hu & Adams 2013, Sec. 4.1).

u = -U cos(2 pi x) sin(2 pi y),  v = U sin(2 pi x) cos(2 pi y)  at t = 0, decaying as
u_max(t) = U exp(-8 pi^2 t / Re),  E_kin(t) / (rho U^2 L^2) = 0.25 exp(-16 pi^2 t / Re),  Re = U L / nu.
E_kin here is (1/2) sum_i m_i |u_i|^2 per unit domain area.

The validated set-up (experiments/tgv2d, JAX-SPH Figs. 4-5): NUMERICS, the three METHODS (the
Effects of each), a start relaxed with RELAXATION (`relax`), compared with the analytical decay
(`u_max_exact`, `e_kin_exact`, `decay_errors`):

    mat = tgv.material(re=100)
    r, _ = tgv.relax(0.02, mat)
    solver = sph.build_solver(tgv.scene(0.02, mat, tgv.METHODS["tvf"], r=r), tgv.NUMERICS)

or in one call `scene, numerics = tgv.setup(0.02, re=100, method="tvf")`.
"""
import sys

import numpy as np

from ..config import Effects, Material, Numerics
from ..domain import Domain
from ..lattice import cartesian, check_run_size, count
from ..relax import Relaxation
from ..scene import Scene
from ..state import FLUID
from .relaxed import relax_periodic, validated_setup

BOX = (1.0, 1.0)
"""The periodic unit square."""

NUMERICS = Numerics(kernel="quintic", h_factor=1.0, cfl=0.25, c_ref_factor=10.0, dtype="float64")
"""The numerics of the validated runs (experiments/tgv2d/config.yaml, profile paper)."""

METHODS = {"sph": Effects(), "tvf": Effects(tvf=True), "riemann": Effects(riemann=True, density_evolution=True)}
"""Standard SPH, transport-velocity SPH (Adami 2013) and Riemann SPH (Zhang 2017b): their Effects."""

RELAXATION = Relaxation(steps=20000, p_bg_factor=0.02, noise_factor=0.25, seed=123, quench_every=200)
"""The relaxed start of the validated runs: JAX-SPH's (TVF, p_bg 0.02 p_ref, noise 0.25 dx, seed 123),
4x longer and with the velocity zeroed every 200 steps, because JAX-SPH's 5000 steps still move at
u_max ~ 0.025 (sph.relax.Relaxation's defaults are JAX-SPH's, not these)."""


def material(re: float, U: float = 1.0, rho_ref: float = 1.0) -> Material:
    """The fluid of Reynolds number re = rho_ref U L / eta (L = 1)."""
    return Material(rho_ref=rho_ref, eta=rho_ref * U / re, u_ref=U)


def relax(dx: float, material: Material, numerics: Numerics = NUMERICS, relaxation: Relaxation = RELAXATION,
          progress: bool = True, desc: str = "relax"):
    """The relaxed start at spacing dx (sph.cases.relaxed.relax_periodic): (positions, info)."""
    return relax_periodic(scene, BOX, dx, material, numerics, relaxation, progress, desc=desc)


def velocity(r, U: float = 1.0) -> np.ndarray:
    x, y = r[:, 0], r[:, 1]
    return np.stack([-U * np.cos(2 * np.pi * x) * np.sin(2 * np.pi * y),
                     U * np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)], axis=1)


def u_max_exact(t, re: float):
    return np.exp(-8.0 * np.pi**2 * np.asarray(t) / re)


def e_kin_exact(t, re: float):
    return 0.25 * np.exp(-16.0 * np.pi**2 * np.asarray(t) / re)


def setup(dx: float, re: float, method: str = "tvf", relaxation: Relaxation = RELAXATION, progress: bool = True):
    """The validated set-up at spacing dx and Reynolds number re (U = 1): (scene on the start relaxed
    with `relaxation`, or on the bare lattice with None; NUMERICS)."""
    return validated_setup(sys.modules[__name__], dx, re, method, relaxation, progress)


def decay_errors(t, u_max, e_kin, re: float) -> dict:
    """Relative errors |sim / exact - 1| of u_max(t) and E_kin(t) (per unit area and density, U = 1)
    against the analytical decay, as arrays over the frames `t`."""
    t = np.asarray(t, float)
    return {"u_max": np.abs(np.asarray(u_max) / u_max_exact(t, re) - 1.0),
            "e_kin": np.abs(np.asarray(e_kin) / e_kin_exact(t, re) - 1.0)}


def scene(dx: float, material: Material, effects: Effects, r=None, name: str = "tgv2d") -> Scene:
    """TGV scene on the unit square; `r` overrides the lattice (e.g. relaxed positions)."""
    if r is None:
        check_run_size(count([0.0, 0.0], [1.0, 1.0], dx), dx, f"scene {name}")
        r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
    r = np.asarray(r, dtype=float)
    return Scene(name=name, dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)), material=material,
                 effects=effects, r=r, u=velocity(r, material.u_ref), tag=np.full(len(r), FLUID, np.int32))
