"""What `build_solver` refuses before anything large is allocated, and the time-step warning.

`check_resolution`: a periodic side shorter than twice the kernel support (a particle would meet its
own image), a walled box too small to hold walls and fluid, walls thinner than the support.
`check_memory`: a run whose particles and neighbour slots cannot fit in the available memory.
`warn_fixed_dt`: a fixed `numerics.dt` above one of the stability limits (`UnstableTimeStep`).
"""
import math
import warnings

import jax
import numpy as np

from .config import Numerics
from .errors import ConfigError
from .scene import Scene


class UnstableTimeStep(UserWarning):
    """A fixed numerics.dt exceeds one of the time-step limits (sph.timestep)."""


class InsufficientMemory(ConfigError, MemoryError):
    """The run would need more memory than is available (estimated before allocating)."""


# bytes per neighbour slot that a step needs at least: the int32 index, the pair geometry
# (dim + 3 floats: dr, |r|, W, dW/dr / r, sph.pairs) and ~4 more floats of pair terms in the physics;
# measured peak temporaries of a jitted step are 2-4x this (XLA memory_analysis, dx 0.02, 2D)
def _bytes_per_slot(dim: int, itemsize: int) -> int:
    return 4 + 1 + (dim + 3 + 4) * itemsize


def neighbour_slots(cutoff: float, skin: float, dx: float, dim: int, capacity_multiplier: float) -> int:
    """Neighbour slots per particle a list allocates: particles within cutoff + skin of a lattice
    (a disc / ball of that radius over dx^dim), times the capacity multiplier."""
    rc = (cutoff + skin) / dx
    ball = math.pi * rc**2 if dim == 2 else (4.0 / 3.0 * math.pi * rc**3 if dim == 3 else 2 * rc)
    return int(math.ceil(capacity_multiplier * ball))


def available_memory() -> tuple:
    """(bytes available to the arrays of a run, where): the default JAX device's free memory on an
    accelerator, the host's available memory (psutil) on CPU."""
    dev = jax.devices()[0]
    if dev.platform != "cpu":
        try:
            stats = dev.memory_stats() or {}
            if "bytes_limit" in stats:
                return int(stats["bytes_limit"] - stats.get("bytes_in_use", 0)), f"{dev.platform} device memory"
        except Exception:  # noqa: BLE001  (memory_stats is optional per backend)
            pass
    import psutil

    return int(psutil.virtual_memory().available), "available host memory"


def check_memory(n: int, dim: int, slots: int, itemsize: int, where: str, dx: float) -> int:
    """Raise InsufficientMemory if `n` particles with `slots` neighbour slots each need more than
    the available memory; returns the estimate (bytes, a lower bound: fields + the list + the pair
    terms of one step)."""
    per_particle = (6 * dim + 6) * itemsize + slots * _bytes_per_slot(dim, itemsize)
    need = n * per_particle
    avail, what = available_memory()
    if need > avail:
        raise InsufficientMemory(
            f"{where}: {n:,} particles (dx = {dx:g}) with {slots} neighbour slots each need at least "
            f"{need / 2**30:.3g} GiB (about {per_particle / 1024:.3g} KiB per particle: fields, neighbour list, "
            f"pair terms), but only {avail / 2**30:.3g} GiB {what} is free: use a larger dx")
    return need


def check_resolution(scene: Scene, cutoff: float, skin: float, numerics: Numerics) -> None:
    """Named ConfigErrors for a scene the kernel cannot resolve (see the module docstring):

    periodic side L < 2 cutoff      the minimum image is no longer unique within the support: a
                                    particle would interact with its own image or twice with a neighbour
    (a fluid body narrower than the support is allowed: a droplet, a jet or a single particle thrown
    at a wall is legitimate physics, resolved or not)
    walled box < 3 cutoff           with walls, a non-periodic side holds less than two wall layers of
                                    the support's thickness and one support of fluid (a cavity at dx 1)
    walls thinner than the support  with walls, a fluid particle closer than `cutoff` to the edge of
                                    the box in a non-periodic dimension (the wall layers, which lie
                                    inside the box, do not cover its support: layers * dx < cutoff)
    """
    where = f"scene {scene.name}"
    dx = scene.dx
    support = (f"the kernel support (cutoff = {cutoff:g} = {cutoff / dx:g} dx with numerics.kernel "
               f"{numerics.kernel!r}, h_factor {numerics.h_factor:g})")
    box = np.asarray(scene.domain.box, float)
    for d, (side, per) in enumerate(zip(box, scene.domain.periodic)):
        if per and side < 2 * cutoff * (1 - 1e-9):
            raise ConfigError(
                f"{where}: dx = {dx:g} is too coarse: the periodic side {d} of length {side:g} is shorter than twice "
                f"{support}, so a particle would interact with its own periodic image; use dx <= "
                f"{side / (2 * cutoff / dx):.4g} (at least {math.ceil(2 * cutoff / dx)} particles across)")
    fluid = scene.r[scene.fluid_mask]
    if scene.effects.walls is not None:
        for d in range(scene.dim):
            if scene.domain.periodic[d]:
                continue
            if box[d] < 3 * cutoff * (1 - 1e-9):
                raise ConfigError(
                    f"{where}: dx = {dx:g} is too coarse: the walled box is {box[d]:g} wide in dimension {d}, less "
                    f"than two wall layers of {support} plus one support of fluid between them ({3 * cutoff:g}); "
                    f"the fluid cannot be resolved: use dx <= {dx * box[d] / (3 * cutoff):.4g}")
            gap = np.minimum(fluid[:, d], box[d] - fluid[:, d])
            i = int(np.argmin(gap))
            if gap[i] < cutoff * (1 - 1e-6):
                layers = int(round((gap[i] - 0.5 * dx) / dx))
                raise ConfigError(
                    f"{where}: the walls are thinner than {support}: fluid particle {int(np.flatnonzero(scene.fluid_mask)[i])} "
                    f"at {fluid[i].tolist()} is {gap[i]:.4g} from the edge of the box in dimension {d}, so its support "
                    f"reaches beyond the wall layers (about {max(layers, 0)} layers of dx; need layers * dx >= cutoff, "
                    f"i.e. at least {math.ceil(cutoff / dx - 1e-9)} wall layers)")


def warn_fixed_dt(scene: Scene, dt: float, limits: dict) -> None:
    """An UnstableTimeStep warning when a fixed dt exceeds one of the time-step limits."""
    over = {k: v for k, v in limits.items() if k != "dt" and dt > v * (1 + 1e-9)}
    if over:
        k = max(over, key=lambda name: dt / over[name])
        warnings.warn(
            f"scene {scene.name}: numerics.dt = {dt:.4g} exceeds the {k} time-step limit {over[k]:.4g} by "
            f"{dt / over[k]:.3g}x (limits: " + ", ".join(f"{n} {v:.3g}" for n, v in limits.items() if n != "dt")
            + "); the run is likely to blow up (it is stopped at the first bad step): lower numerics.dt or "
            "set it to null", UnstableTimeStep, stacklevel=3)
