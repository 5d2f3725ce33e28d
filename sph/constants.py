"""The constants of a run, derived once from (scene, numerics): kernel, sound speed, equation of
state, background pressures, body force and time step (Adami 2013 Sec. 2-3, Zhang 2017b)."""
from dataclasses import dataclass
from typing import Optional

import jax.numpy as jnp

from . import registry, walls
from .config import Numerics
from .eos import RiemannEoS, TaitEoS
from .errors import ConfigError
from .forces import ConstantForce
from .kernels import make_kernel
from .precision import resolve
from .scene import Scene
from .timestep import time_step


@dataclass(frozen=True)
class Constants:
    """h, kernel, W(0) (`w0`), c_ref = c_ref_factor u_ref, p_ref = rho_ref c_ref^2 / gamma (Tait) or
    rho_ref c_ref^2 (Riemann), the EoS with background pressure p_bg, the TVF background pressure
    p_b, the body force (None: none), the time-step limits and dt, the neighbour skin, the dtype and
    the float32 weight floor of the wall extrapolation (`sph.walls.fluid_weights`)."""

    h: float
    kernel: object
    w0: float
    c_ref: float
    eos: object
    p_b: float
    force: Optional[object]
    limits: dict
    dt: float
    skin: float
    dtype: object
    weight_floor: float

    @property
    def margin(self) -> float:
        """cutoff + skin: the reach of the neighbour list."""
        return self.kernel.cutoff + self.skin


def derive(scene: Scene, numerics: Numerics) -> Constants:
    fx, mat = scene.effects, scene.material
    dtype = resolve(numerics.dtype)
    h = numerics.h_factor * scene.dx
    kernel = make_kernel(numerics.kernel, h, scene.dim)
    c_ref = numerics.c_ref_factor * mat.u_ref
    p_ref = mat.rho_ref * c_ref**2 / (1.0 if fx.riemann else numerics.gamma)
    p_bg = numerics.p_bg_factor * p_ref
    eos = RiemannEoS(mat.rho_ref, c_ref, p_bg=p_bg) if fx.riemann else TaitEoS(mat.rho_ref, c_ref, numerics.gamma, p_bg=p_bg)
    force = scene.body_force
    if fx.gravity is not None:
        if len(fx.gravity) != scene.dim:
            raise ConfigError(f"effects.gravity: has {len(fx.gravity)} components but the scene is {scene.dim}D")
        force = ConstantForce(tuple(float(g) for g in fx.gravity))
    g_max = force.g_max if force is not None else 0.0
    diffusivity = mat.kappa / (mat.rho_ref * mat.c_p) if fx.heat else 0.0
    limits = time_step(h, c_ref, mat.u_ref, mat.eta, mat.rho_ref, g_max, numerics.cfl, diffusivity)
    extra = registry.dt_limits(scene, numerics, h)
    if extra:
        limits = {**{k: v for k, v in limits.items() if k != "dt"}, **extra}
        limits["dt"] = min(limits.values())
    w0 = float(kernel.w(0.0))
    # float32 only: there 1 / sum^2 of a kernel-tail weight sum overflows (walls.fluid_weights);
    # float64 keeps the exact derivative, which the gradient check needs
    floor = walls.WEIGHT_FLOOR * w0 if jnp.dtype(dtype) == jnp.float32 else 0.0
    return Constants(h=h, kernel=kernel, w0=w0, c_ref=float(c_ref), eos=eos, p_b=numerics.p_b_factor * p_ref,
                     force=force, limits=limits, dt=float(numerics.dt if numerics.dt is not None else limits["dt"]),
                     skin=numerics.skin_factor * scene.dx, dtype=dtype, weight_floor=floor)
