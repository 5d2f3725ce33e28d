"""What `build_solver` refuses before anything large is allocated, and the time-step warning.

`check_resolution`: a periodic side shorter than twice the kernel support (a particle would meet its
own image), a walled box too small to hold walls and fluid, walls thinner than the support.
`check_memory`: a run whose particles and neighbour slots cannot fit in the available memory.
`warn_fixed_dt`: a fixed `numerics.dt` above one of the stability limits (`UnstableTimeStep`).
`check_start` (in `init_fn`, on the start's neighbour list): coincident particles, fluid without
neighbours, positions made for another dx, and the physical invariants of the start (summation
density = partition of unity, gradient consistency) within stated tolerances.
"""
import math
import warnings
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from .pairs import sum_j
from .pvec import dot

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


def _round_down(x: float, digits: int = 4) -> str:
    """x rounded down to `digits` significant digits: a suggested bound that itself passes."""
    scale = 10 ** (digits - 1 - math.floor(math.log10(x)))
    return f"{math.floor(x * scale) / scale:g}"


def _coarsest_walled_dx(side: float, fluid, d: int, walled, dx: float, cutoff: float) -> str:
    """The largest dx whose walled box holds two supports of walls and one of fluid, for a box that
    is built as L + 2 layers dx (the wall layers shrink with dx): L + 2 l dx >= 3 s dx, with the
    support s = cutoff / dx, the layers l and the fluid span L read off this scene; suggested as the
    largest L / n below that bound that also divides the fluid's extent in every walled dimension
    into whole spacings (a scene built from whole spacings can be built at it)."""
    layers = max(int(round((float(np.min(fluid[:, d])) - 0.5 * dx) / dx)), 0)
    span = side - 2 * layers * dx
    s = cutoff / dx
    if 3 * s - 2 * layers <= 0 or span <= 0:
        return "use more wall layers or a finer dx"
    bound = span / (3 * s - 2 * layers)
    # the fluid's extent per walled dimension (a lattice of whole spacings: ptp + dx); one within a
    # spacing of the span fills the box (a cavity built at a dx that does not divide it)
    extents = [e if abs(e - span) >= dx else span for e in (float(np.ptp(fluid[:, k])) + dx for k in walled)]
    for n in range(math.ceil(span / bound - 1e-9), math.ceil(span / bound - 1e-9) + 200):
        cand = span / n
        if all(abs(e / cand - round(e / cand)) < 1e-6 for e in extents):
            return (f"use dx = {cand:.10g} or finer (the coarsest whole division of the span {span:g} and of the "
                    f"fluid with {layers} wall layers)")
    return f"use dx <= {_round_down(bound)} (with {layers} wall layers around a span of {span:g})"


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
                f"{support}, so a particle would interact with its own periodic image; use dx = "
                f"{side / math.ceil(2 * cutoff / dx - 1e-9):.10g} or finer (at least {math.ceil(2 * cutoff / dx - 1e-9)} "
                f"particles across)")
    fluid = scene.r[scene.fluid_mask]
    if scene.effects.walls is not None:
        for d in range(scene.dim):
            if scene.domain.periodic[d]:
                continue
            if box[d] < 3 * cutoff * (1 - 1e-9):
                raise ConfigError(
                    f"{where}: dx = {dx:g} is too coarse: the walled box is {box[d]:g} wide in dimension {d}, less "
                    f"than two wall layers of {support} plus one support of fluid between them ({3 * cutoff:g}); "
                    f"the fluid cannot be resolved: "
                    f"{_coarsest_walled_dx(box[d], fluid, d, [k for k in range(scene.dim) if not scene.domain.periodic[k]], dx, cutoff)}")
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
