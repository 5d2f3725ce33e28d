"""Particle lattices: cell-centred Cartesian grids with optional Gaussian noise.

`cartesian` counts its points before allocating them and refuses (`InsufficientMemory`, naming the
count, dx and the memory needed and available) a lattice whose arrays cannot fit in the available
host memory, instead of dying inside numpy; `sph.build_solver` checks the memory of the whole run.
"""
import math

import numpy as np

from .errors import ConfigError


def _check_lattice(counts, dx) -> None:
    """Refuse a lattice whose construction (meshgrid, stacked copy, float64) exceeds the available
    host memory."""
    if not math.isfinite(float(dx)) or float(dx) <= 0:
        raise ConfigError(f"lattice: dx must be a positive finite number, got {dx}")
    n = math.prod(int(c) for c in counts)
    need = 3 * n * len(counts) * 8  # the meshgrid arrays, their stacked copy and a ravel temporary
    if need < 2**28:  # under 256 MiB: never worth a system call
        return
    import psutil

    from .memory import InsufficientMemory

    avail = psutil.virtual_memory().available
    if need > avail:
        raise InsufficientMemory(
            f"lattice: {n:,} particles ({' x '.join(str(int(c)) for c in counts)} at dx = {dx:g}) need "
            f"{need / 2**30:.3g} GiB just to build their positions, but only {avail / 2**30:.3g} GiB of host memory "
            f"is available (a run needs ~100x more, see sph.solver.check_memory): use a larger dx")


def count(lo, hi, dx) -> int:
    """Number of points `cartesian(lo, hi, dx)` would make (nothing is allocated)."""
    lo, hi = np.atleast_1d(lo).astype(float), np.atleast_1d(hi).astype(float)
    if not (math.isfinite(float(dx)) and float(dx) > 0):
        raise ConfigError(f"lattice: dx must be a positive finite number, got {dx}")
    return math.prod(int(c) for c in np.round((hi - lo) / dx).astype(int))


# the least a step needs per particle whatever the numerics: ~20 float64 fields and ~12 neighbour
# slots (a disc of radius 2 dx, the narrowest support) of ~40 bytes; sph.solver.check_memory refines it
MIN_RUN_BYTES_PER_PARTICLE = 20 * 8 + 12 * 40


def check_run_size(n: int, dx: float, where: str) -> None:
    """Refuse, before any array exists, a scene of `n` particles that no run could fit into the
    available host memory (a lower bound, MIN_RUN_BYTES_PER_PARTICLE; the case builders call this)."""
    need = n * MIN_RUN_BYTES_PER_PARTICLE
    if need < 2**30:
        return
    import psutil

    from .memory import InsufficientMemory

    avail = psutil.virtual_memory().available
    if need > avail:
        raise InsufficientMemory(
            f"{where}: dx = {dx:g} makes {n:,} particles; a run needs at least {need / 2**30:.3g} GiB "
            f"(~{MIN_RUN_BYTES_PER_PARTICLE} bytes per particle, more with the default kernel: "
            f"sph.solver.check_memory), but only {avail / 2**30:.3g} GiB of host memory is available: use a larger dx")


def cartesian(lo, hi, dx) -> np.ndarray:
    """Cell-centred lattice filling the box [lo, hi) with spacing dx: (N, dim)."""
    lo, hi = np.atleast_1d(lo).astype(float), np.atleast_1d(hi).astype(float)
    if not (math.isfinite(float(dx)) and float(dx) > 0):
        raise ConfigError(f"lattice: dx must be a positive finite number, got {dx}")
    counts = np.round((hi - lo) / dx).astype(int)
    _check_lattice(counts, dx)
    axes = [lo[d] + (np.arange(counts[d]) + 0.5) * dx for d in range(len(lo))]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in grid], axis=1)


def jitter(r, std, seed, box=None) -> np.ndarray:
    """Add Gaussian noise of standard deviation `std` (fixed seed); wrap into a periodic `box`."""
    rng = np.random.default_rng(seed)
    out = r + rng.normal(scale=std, size=r.shape)
    if box is not None:
        out = np.mod(out, np.asarray(box, dtype=float))
    return out


def wall_layers(lo, hi, dx, layers: int, open_sides=()):
    """Wall particles framing the fluid box [lo, hi): `layers` cell-centred layers on every side
    except those in `open_sides` (entries (axis, 0) for the low side, (axis, 1) for the high side).

    Returns positions (M, dim) and unit normals (M, dim) pointing from each wall particle to the
    nearest point of the fluid box (diagonal at corners), as Riemann and free-slip walls need.
    """
    lo, hi = np.atleast_1d(lo).astype(float), np.atleast_1d(hi).astype(float)
    pad = layers * dx
    r = cartesian(lo - pad, hi + pad, dx)
    outside = np.any((r < lo) | (r > hi), axis=1)
    for axis, side in open_sides:
        beyond = r[:, axis] > hi[axis] if side else r[:, axis] < lo[axis]
        outside &= ~beyond
    r = r[outside]
    to_fluid = np.clip(r, lo, hi) - r
    normal = to_fluid / np.linalg.norm(to_fluid, axis=1, keepdims=True)
    return r, normal
