"""Particle lattices: cell-centred Cartesian grids with optional Gaussian noise."""
import numpy as np


def cartesian(lo, hi, dx) -> np.ndarray:
    """Cell-centred lattice filling the box [lo, hi) with spacing dx: (N, dim)."""
    lo, hi = np.atleast_1d(lo).astype(float), np.atleast_1d(hi).astype(float)
    counts = np.round((hi - lo) / dx).astype(int)
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
