"""Relaxed starts of a periodic box (JAX-SPH's 'rlx' mode): the lattice of spacing dx, jittered by
Gaussian noise (std relaxation.noise_factor * dx, relaxation.seed), relaxed at rest with TVF and an
EoS background pressure (sph.relax). The TGV cases (sph.cases.tgv, sph.cases.tgv3d) relax their
starts with it; their RELAXATION is the recipe the validated runs use.
"""
from typing import Callable

import numpy as np

from .. import relax as core_relax
from ..config import Effects
from ..errors import require
from ..lattice import cartesian, jitter


def relax_periodic(scene_fn: Callable, box: tuple, dx: float, material, numerics, relaxation,
                   progress: bool = True, desc: str = "relax"):
    """Relax the lattice of spacing `dx` filling the periodic `box`, jittered by Gaussian noise (std
    relaxation.noise_factor * dx, relaxation.seed), at rest with TVF (sph.relax); `scene_fn(dx,
    material, effects, r=r)` builds the case's scene. Returns (positions, info)."""
    r = jitter(cartesian([0.0] * len(box), list(box), dx), relaxation.noise_factor * dx, relaxation.seed, box=box)
    r = np.where(r >= np.asarray(box), 0.0, r)  # np.mod can round a tiny negative up to exactly the box side
    scene = scene_fn(dx, material, Effects(tvf=True), r=r)
    return core_relax.relax(scene, numerics, relaxation, progress, desc=desc)


def validated_setup(case, dx: float, re: float, method: str, relaxation, progress: bool):
    """A periodic case module's validated set-up (`case` has METHODS, NUMERICS, material, relax and
    scene): (scene on the start relaxed with `relaxation`, or on the bare lattice with None; NUMERICS)."""
    require(method in case.METHODS, "method", f"{method!r} is not one of {list(case.METHODS)}")
    mat = case.material(re)
    r = None if relaxation is None else case.relax(dx, mat, case.NUMERICS, relaxation, progress)[0]
    return case.scene(dx, mat, case.METHODS[method], r=r), case.NUMERICS
