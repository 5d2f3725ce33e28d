"""Relaxed initial particle positions for the 2D Taylor-Green vortex (JAX-SPH 'rlx' mode).

A Cartesian lattice jittered by Gaussian noise (std noise_factor * dx, fixed seed) is advanced at
rest (zero initial velocity) with the transport-velocity formulation and an EoS background pressure
p_bg_factor * p_ref, until the particles settle into an even, non-lattice distribution. The result is
cached in results/<profile>/tgv2d/relaxed_dx<dx>.npy with a .json sidecar; the cache is reused only
when its fingerprint (relaxation settings, material, numerics, code) matches.

    python experiments/tgv2d/relax.py --profile smoke [--results results/smoke]
"""
import dataclasses

import numpy as np

import sph
from sph import relax as core_relax
from sph.harness import runs
from sph.cases import tgv
from sph.lattice import cartesian, jitter

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def relax(exp: "S.Experiment", dx: float, progress: bool = True):
    """Relax the jittered lattice of spacing `dx` (sph.relax); returns (positions (N, 2), info)."""
    rlx = exp.relaxation
    box = (1.0, 1.0)
    r = jitter(cartesian([0.0, 0.0], list(box), dx), rlx.noise_factor * dx, rlx.seed, box=box)
    r = np.where(r >= 1.0, 0.0, r)  # np.mod can round a tiny negative up to exactly the box side
    scene = tgv.scene(dx, exp.material, sph.Effects(tvf=True), r=r)
    return core_relax.relax(scene, exp.numerics, rlx, progress, desc=f"relax {S.dx_tag(dx)}")


def relaxed_positions(exp: "S.Experiment", dx: float, results, progress: bool = True) -> np.ndarray:
    """Cached relaxed positions for spacing `dx` (computed and saved when missing or stale)."""
    return runs.cached_positions(S.relaxed_path(results, dx), S.relax_fingerprint(exp, dx),
                                 lambda: relax(exp, dx, progress), f"relaxed {S.dx_tag(dx)}", dx=dx,
                                 relaxation=dataclasses.asdict(exp.relaxation))


def options(ap):
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    exp = S.load(args.profile)
    results = args.results
    for dx in exp.dx:
        relaxed_positions(exp, dx, results, progress=not args.no_progress)


if __name__ == "__main__":
    from sph.harness.cli import profile_main

    profile_main(main, __doc__, options)
