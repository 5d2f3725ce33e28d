"""Whether a run fits in memory, estimated before anything large is allocated (`build_solver`).

`check_memory`: a run whose particles and neighbour slots cannot fit in the available memory
(`InsufficientMemory`, naming the size and what to change); `neighbour_slots`: the slots per particle
a list allocates; `available_memory`: the default device's free memory, or the host's on CPU.
"""
import math

import jax

from .errors import ConfigError


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
