"""Relaxed initial particle positions for the 3D Taylor-Green vortex (JAX-SPH 'rlx' mode, as tgv2d).

The cell-centred lattice of the box (2 pi)^3, jittered by Gaussian noise (std noise_factor * dx,
fixed seed), is advanced at rest with the transport-velocity formulation and an EoS background
pressure p_bg_factor * p_ref (sph.relax), the velocity zeroed every `quench_every` steps. Cached in
results/<profile>/tgv3d/relaxed_n<n>.npy with a .json sidecar; the cache is reused only when its
fingerprint (relaxation settings, material, numerics, code) matches.

    python experiments/tgv3d/relax.py --profile smoke [--results results/smoke]
"""
import dataclasses

import numpy as np

import sph
from sph import relax as core_relax
from sph.harness import runs
from sph.cases import tgv3d
from sph.lattice import cartesian, jitter

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def relax(exp: "S.Experiment", n: int, progress: bool = True):
    """Relax the jittered lattice of n^3 particles (sph.relax); returns (positions (n^3, 3), info)."""
    rlx, dx = exp.relaxation, exp.dx(n)
    box = (tgv3d.SIDE,) * 3
    r = jitter(cartesian([0.0] * 3, list(box), dx), rlx.noise_factor * dx, rlx.seed, box=box)
    r = np.where(r >= tgv3d.SIDE, 0.0, r)  # np.mod can round a tiny negative up to exactly the box side
    scene = tgv3d.scene(dx, exp.material, sph.Effects(tvf=True), r=r)
    return core_relax.relax(scene, exp.numerics, rlx, progress, desc=f"relax {S.n_tag(n)}")


def relaxed_positions(exp: "S.Experiment", n: int, results, progress: bool = True) -> np.ndarray:
    """Cached relaxed positions for n^3 particles (computed and saved when missing or stale)."""
    return runs.cached_positions(S.relaxed_path(results, n), S.relax_fingerprint(exp, n),
                                 lambda: relax(exp, n, progress), f"relaxed {S.n_tag(n)}", n_side=n, dx=exp.dx(n),
                                 relaxation=dataclasses.asdict(exp.relaxation))


def initial_positions(exp: "S.Experiment", n: int, results, progress: bool = True):
    """The start of the runs at n^3 particles: relaxed positions, or None (the scene's lattice)."""
    return relaxed_positions(exp, n, results, progress) if exp.start == "relaxed" else None


def options(ap):
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    exp = S.load(args.profile)
    results = args.results
    for n in exp.n_side:
        relaxed_positions(exp, n, results, progress=not args.no_progress)


if __name__ == "__main__":
    from sph.harness.cli import profile_main

    profile_main(main, __doc__, options)
