"""Relaxed initial particle positions for the 3D Taylor-Green vortex (JAX-SPH 'rlx' mode, as tgv2d).

The cell-centred lattice of the box (2 pi)^3, jittered by Gaussian noise (std noise_factor * dx,
fixed seed), is advanced at rest with the transport-velocity formulation and an EoS background
pressure p_bg_factor * p_ref, the velocity zeroed every `quench_every` steps (the same relaxation
as tgv2d's: sph.cases.tgv3d.relax, whose RELAXATION is the paper profile's). Cached in
results/<profile>/tgv3d/relaxed_n<n>.npy with a .json sidecar; the cache is reused only when its
fingerprint (relaxation settings, material, numerics, code) matches.

    python experiments/tgv3d/relax.py --profile smoke [--results results/smoke]
"""
import dataclasses

from sph.cases import tgv3d
from lab import runs
from lab.cli import profile_main

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def relax(exp: "S.Experiment", n: int, progress: bool = True):
    """Relax the jittered lattice of n^3 particles (sph.cases.tgv3d.relax, as tgv2d);
    returns (positions (n^3, 3), info)."""
    return tgv3d.relax(exp.dx(n), exp.material, exp.numerics, exp.relaxation, progress, desc=f"relax {S.n_tag(n)}")


def relaxed_positions(exp: "S.Experiment", n: int, results, progress: bool = True):
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
    for n in exp.n_side:
        relaxed_positions(exp, n, args.results, progress=not args.no_progress)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
