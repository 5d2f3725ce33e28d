"""2D channel periodic in x between two flat no-slip walls, optionally with a heated wall segment:
JAX-SPH's heat-transfer case (Toshev et al. 2024, Fig. 10; `cases/ht.py` of tumaer/jax-sph).

Geometry (scene coordinates): the box is [0, length) x [0, height + 2 layers dx), periodic in x only.
The fluid fills [0, length) x [off, off + height) with off = layers * dx (cell-centred lattice,
optionally with Gaussian position noise of std noise_factor * dx on the fluid only, wrapped in x);
`layers` rows of wall particles lie below (y < off) and above (y >= off + height), over the full
length. The flow is driven by a body force (effects.gravity, e.g. (2.3, 0)), or by the top wall
moving at `wall_velocity` along x (tag MOVING_WALL: plane Couette flow, `couette_profile`); the
solver zeroes the acceleration of wall particles.

With effects.heat every wall particle is a Dirichlet particle (scene.T_fixed): T_ref everywhere
except the bottom-wall segment |x - hot_center| < hot_half_width (all its layers), held at T_hot.
The fluid starts at T_ref. With zone_layers > 0 two temperature zones close the periodic loop as
in JAX-SPH: fluid with x < zone_layers dx is an inflow held at T_ref, fluid with
x >= length - zone_layers dx an outflow with dT/dt = 0.
"""
import numpy as np

from ..config import Effects, Material
from ..domain import Domain
from ..heat import TemperatureZone
from ..lattice import cartesian, check_run_size, count
from ..scene import Scene
from ..state import FLUID, MOVING_WALL, WALL


def _whole(value: float, dx: float, what: str) -> int:
    n = value / dx
    if abs(n - round(n)) > 1e-6 or round(n) < 1:
        raise ValueError(f"channel: {what} = {value:g} is not a whole number of spacings dx = {dx:g}")
    return int(round(n))


def offset(dx: float, layers: int = 3) -> float:
    """y of the bottom fluid boundary in scene coordinates (the wall thickness)."""
    return layers * dx


def hot_wall_mask(r: np.ndarray, dx: float, layers: int = 3, hot_center: float = 0.5,
                  hot_half_width: float = 0.25) -> np.ndarray:
    """Particles of the heated bottom-wall segment: y < off and |x - hot_center| < hot_half_width."""
    r = np.asarray(r)
    return (r[:, 1] < offset(dx, layers)) & (np.abs(r[:, 0] - hot_center) < hot_half_width)


def zones(dx: float, length: float, zone_layers: int, T_ref: float) -> tuple:
    """Inflow (x < zone_layers dx, held at T_ref) and outflow (x >= length - zone_layers dx, dT/dt = 0)."""
    if zone_layers <= 0:
        return ()
    width = zone_layers * dx
    return (TemperatureZone(axis=0, lo=-np.inf, hi=width, T=float(T_ref)),
            TemperatureZone(axis=0, lo=length - width, hi=np.inf, T=None))


def scene(dx: float, material: Material, effects: Effects, length: float = 1.0, height: float = 0.2,
          layers: int = 3, noise_factor: float = 0.0, seed: int = 123, T_ref: float = 1.0,
          T_hot: float = 1.23, hot_center: float = None, hot_half_width: float = 0.25, zone_layers: int = 3,
          wall_velocity: float = 0.0, name: str = "channel2d") -> Scene:
    """The channel at spacing dx (module docstring); `wall_velocity` moves the top wall along x."""
    nx = _whole(length, dx, "length")
    _whole(height, dx, "height")
    if layers < 1:
        raise ValueError(f"channel: needs at least one wall layer, got layers = {layers}")
    off = offset(dx, layers)
    check_run_size(count([0.0, 0.0], [length, height + 2 * off], dx), dx, f"scene {name}")
    fluid = cartesian([0.0, off], [length, off + height], dx)
    if noise_factor > 0:
        rng = np.random.default_rng(seed)
        fluid = fluid + rng.normal(scale=noise_factor * dx, size=fluid.shape)
        fluid[:, 0] = np.mod(fluid[:, 0], length)
    bottom = cartesian([0.0, 0.0], [length, off], dx)
    top = cartesian([0.0, off + height], [length, height + 2 * off], dx)
    assert len(bottom) == len(top) == nx * layers
    r = np.concatenate([fluid, bottom, top])
    n_f, n_w = len(fluid), len(bottom)
    top_tag = MOVING_WALL if wall_velocity else WALL
    tag = np.concatenate([np.full(n_f, FLUID), np.full(n_w, WALL), np.full(n_w, top_tag)]).astype(np.int32)
    normal = np.concatenate([np.zeros_like(fluid), np.tile([0.0, 1.0], (n_w, 1)), np.tile([0.0, -1.0], (n_w, 1))])
    extra = {}
    if effects.heat:
        hot = hot_wall_mask(r, dx, layers, length / 2 if hot_center is None else hot_center, hot_half_width)
        extra = dict(T=np.where(hot, T_hot, T_ref).astype(float), T_fixed=tag != FLUID,
                     T_zones=zones(dx, length, zone_layers, T_ref))
    box = (float(length), float(height + 2 * off))
    u = np.zeros_like(r)
    u[tag == MOVING_WALL, 0] = wall_velocity
    return Scene(name=name, dx=dx, domain=Domain(box=box, periodic=(True, False)), material=material,
                 effects=effects, r=r, u=u, tag=tag, normal=normal, **extra)


def couette_profile(y, t, wall_velocity: float, height: float, nu: float, n_modes: int = 200) -> np.ndarray:
    """u(y, t) of plane Couette flow started from rest (the top wall set moving at t = 0), y from the
    bottom wall face: U y / H - (2 U / pi) sum_n (-1)^(n+1) / n sin(n pi y / H) exp(-nu (n pi / H)^2 t)
    (the steady linear profile minus the decaying transient; Schlichting & Gersten, Boundary-Layer
    Theory, Sec. 15.1)."""
    y = np.asarray(y, float)
    n = np.arange(1, n_modes + 1)[:, None]
    k = n * np.pi / height
    transient = ((-1.0) ** (n + 1) / n * np.sin(k * y[None, :]) * np.exp(-nu * k**2 * t)).sum(axis=0)
    return wall_velocity * (y / height - 2.0 / np.pi * transient)
