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
