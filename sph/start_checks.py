"""The start checked before step 1 (`init_fn`, on the start's neighbour list): coincident particles,
fluid without neighbours, positions made for another dx, and the physical invariants of the start
(summation density = partition of unity, gradient consistency) within stated tolerances
(`check_start`; the per-particle sums are the pass term `StartInvariants`).
"""
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from .config import Numerics
from .errors import ConfigError
from .pairs import sum_j
from .pvec import dot
from .scene import Scene


MIN_NEIGHBOURS = {1: 2, 2: 8, 3: 18}
"""Fewest neighbours within the kernel support a typical fluid particle may have: its first lattice
shell (2D: 4 sides + 4 diagonals; 3D: 6 faces + 12 edges). Below that the SPH sums are no longer
approximations of integrals (a quintic kernel at h = dx has ~28 in 2D, ~110 in 3D)."""
SPACING_RANGE = (0.5, 1.6)
"""Allowed median nearest-neighbour distance of the fluid particles, in units of scene.dx: a lattice
gives 1, a relaxed or jittered one 0.85-1; outside, the particles were made for another dx."""


DENSITY_TOLERANCE = 0.10
"""How far the median Shepard sum sum_j V_j W_ij (self term included, V = m / rho_ref) of the interior
fluid particles may lie from 1 on the start. With V = m / rho_ref it is both the summation density
over rho_ref and the kernel's partition of unity. A lattice gives 1.0001 (2D and 3D), a relaxed start
1 +- 0.01, an unrelaxed 0.25 dx Gaussian jitter +0.05 ... +0.06; a spacing 5 % off dx gives 0.10 (2D),
0.16 (3D), positions of spacing 0.04 at dx 0.05 1.56, h_factor 0.5 1.31."""
GRADIENT_TOLERANCE = 0.25
"""How far the median over the interior fluid of max_ab |M_ab / S - delta_ab| may be from 0, with
M = sum_j V_j (r_j - r_i) (x) grad_i W_ij (= I for an exact gradient) and S the Shepard sum: the
kernel's gradient consistency. Lattice: 0.0008 at h = dx, 0.012 at 0.8 dx, 0.08 at 0.7 dx, 0.28 at
0.6 dx, 0.63 at 0.5 dx; an unrelaxed 0.25 dx jitter 0.16."""
INTERIOR = 0.3
"""A fluid particle counts as interior (its support full: no free surface near it) where
|sum_j V_j grad_i W_ij| h < INTERIOR: 0 on a lattice, median 0.2 for a 0.25 dx jitter, about 0.5 on a
free surface."""


@dataclass(frozen=True)
class StartInvariants:
    """A pass term over the start: per particle its nearest neighbour's distance and index, the number
    of neighbours within the kernel support `cutoff`, the Shepard sum S = V_i W(0) + sum_j V_j W_ij,
    |sum_j V_j grad_i W_ij| h (0 where the support is full) and the gradient-consistency matrix
    M = sum_j V_j (r_j - r_i) (x) grad_i W_ij (row-major entries), with V = `vol` (m / rho_ref)."""

    cutoff: float
    w0: float
    h: float
    reads = ("r", "vol")

    def __call__(self, pp, i, j):
        d = jnp.where(pp.mask, pp.d, jnp.inf)
        k = jnp.argmin(d, axis=-1, keepdims=True)
        count = jnp.sum(pp.mask & (pp.d < self.cutoff), axis=-1, keepdims=True)
        shepard = i.vol * self.w0 + sum_j(j.vol * pp.w)
        g = sum_j(j.vol * pp.grad_w)
        m = tuple(sum_j(j.vol * (-a) * b) for a in pp.dr.c for b in pp.grad_w.c)
        return (jnp.take_along_axis(d, k, -1), jnp.take_along_axis(pp.j, k, -1), count, shepard,
                jnp.sqrt(dot(g, g)) * self.h) + m


def check_start(scene: Scene, invariants, cutoff: float, numerics: Numerics) -> None:
    """Named ConfigErrors, before a step is taken, for a start the physics cannot treat (checked in
    this order, each a one-line message naming the key to change):

    - coincident particles (a pair closer than 1e-3 dx: r_ij = 0 makes every pair term singular);
    - fluid particles without a neighbour in the kernel support (positions far sparser than dx);
    - a median spacing outside SPACING_RANGE dx (positions made for another resolution);
    - fewer than MIN_NEIGHBOURS neighbours of a typical fluid particle (h_factor too small);
    - the physical invariants of the interior fluid (INTERIOR): the Shepard sum, which is the
      summation density over rho_ref and the partition of unity, within DENSITY_TOLERANCE of 1, and
      the kernel's gradient consistency within GRADIENT_TOLERANCE. These catch any mismatch of
      lattice and dx (in any dimension) and a kernel too small to resolve the sums, however many
      neighbours it reaches.

    A scene with fewer fluid particles than 4 MIN_NEIGHBOURS (a single particle thrown at a wall) is
    legitimate physics, resolved or not, and only checked for coincident particles; the invariants
    are checked where at least that many fluid particles are interior."""
    dx, dim, where = scene.dx, scene.dim, f"scene {scene.name}"
    nearest, nearest_j, count, shepard, g_h, *m = (np.asarray(x) for x in invariants)
    i = int(np.argmin(nearest))
    if nearest[i] < 1e-3 * dx:
        raise ConfigError(
            f"{where}: particles {i} and {int(nearest_j[i])} coincide (distance {nearest[i]:.3g} < 1e-3 dx, at "
            f"{np.round(scene.r[i], 6).tolist()}): every pair term is singular there; remove the duplicate")
    fluid, need = scene.fluid_mask, MIN_NEIGHBOURS[dim]
    if fluid.sum() < 4 * need:
        return                                        # too few to have an interior: nothing typical to check
    alone = fluid & (count == 0)
    if alone.sum() > fluid.sum() // 2:
        seen = nearest[fluid & np.isfinite(nearest)]
        apart = f"{float(np.median(seen)):.4g}" if seen.size else f"more than {cutoff + numerics.skin_factor * dx:.4g}"
        raise ConfigError(
            f"{where}: {int(alone.sum())} of {int(fluid.sum())} fluid particles have no neighbour within the kernel "
            f"support {cutoff:.4g} ({cutoff / dx:.3g} dx): the particles are {apart} apart, far more than scene.dx = "
            f"{dx:g}; set dx to their spacing or rebuild the positions for dx = {dx:g}")
    has = fluid & np.isfinite(nearest)
    spacing = float(np.median(nearest[has]))
    lo, hi = SPACING_RANGE
    if not lo * dx <= spacing <= hi * dx:
        raise ConfigError(
            f"{where}: the fluid particles' spacing (median nearest-neighbour distance {spacing:.4g}) is "
            f"{spacing / dx:.3g} dx for scene.dx = {dx:g}: the particles were made for another resolution "
            f"(masses rho_ref dx^dim would put the density near {(dx / spacing) ** dim:.3g} rho_ref); "
            f"set dx = {spacing:.4g} or rebuild the positions for dx = {dx:g}")
    typical = float(np.median(count[has]))
    if typical < need:
        raise ConfigError(
            f"numerics.h_factor: {numerics.h_factor:g} gives a kernel support of {cutoff / dx:.3g} dx with "
            f"{typical:.0f} neighbours per fluid particle (median), fewer than {need} (the first lattice shell): "
            f"the SPH sums are not resolved; raise numerics.h_factor")
    interior = has & (count >= need) & (g_h < INTERIOR)
    if interior.sum() < 4 * need:
        return
    s = float(np.median(shepard[interior]))
    if abs(s - 1.0) > DENSITY_TOLERANCE:
        if abs(spacing / dx - 1.0) > 0.02:
            raise ConfigError(
                f"{where}: the interior fluid's summation density is {s:.3g} rho_ref on the start (allowed 1 +- "
                f"{DENSITY_TOLERANCE:g}): its particles are {spacing:.4g} apart (median), {spacing / dx:.3g} dx for "
                f"scene.dx = {dx:g}, so masses rho_ref dx^dim are wrong for them; set dx = {spacing:.4g} or rebuild "
                f"the positions for dx = {dx:g}")
        raise ConfigError(
            f"numerics.h_factor: {numerics.h_factor:g} (kernel support {cutoff / dx:.3g} dx) gives a partition of "
            f"unity sum V W = {s:.3g} on the interior of the start (allowed 1 +- {DENSITY_TOLERANCE:g}): the kernel "
            f"does not resolve the SPH sums; raise numerics.h_factor (1.0 gives 1.0001)")
    eye = np.eye(dim).reshape(-1)
    dev = np.abs(np.stack(m, -1)[interior] / shepard[interior][:, None] - eye).max(-1)
    e = float(np.median(dev))
    if e > GRADIENT_TOLERANCE:
        raise ConfigError(
            f"numerics.h_factor: {numerics.h_factor:g} (kernel support {cutoff / dx:.3g} dx) gives a kernel gradient "
            f"off by {e:.2g} on the interior of the start (sum V (r_j - r_i) grad W = I within {GRADIENT_TOLERANCE:g}): "
            f"the kernel does not resolve the SPH gradients; raise numerics.h_factor (1.0 gives 0.001)")
