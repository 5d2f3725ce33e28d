"""What `build_solver` refuses before anything large is allocated, and the time-step warning.

`check_resolution`: a periodic side shorter than twice the kernel support (a particle would meet its
own image), a walled box too small to hold walls and fluid, walls thinner than the support.
`warn_fixed_dt`: a fixed `numerics.dt` above one of the stability limits (`UnstableTimeStep`).
The memory estimate is `sph.memory`'s, the checks of the start's particles `sph.start_checks`'.
"""
import math
import warnings

import numpy as np

from .config import Numerics
from .errors import ConfigError
from .scene import Scene


class UnstableTimeStep(UserWarning):
    """A fixed numerics.dt exceeds one of the time-step limits (sph.timestep)."""


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
