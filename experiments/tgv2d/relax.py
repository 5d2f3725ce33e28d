"""Relaxed initial particle positions for the 2D Taylor-Green vortex (JAX-SPH 'rlx' mode).

A Cartesian lattice jittered by Gaussian noise (std noise_factor * dx, fixed seed) is advanced at
rest (zero initial velocity) with the transport-velocity formulation and an EoS background pressure
p_bg_factor * p_ref, until the particles settle into an even, non-lattice distribution
(sph.cases.tgv.relax). The result is cached in results/<profile>/tgv2d/relaxed_dx<dx>.npy
with a .json sidecar; the cache is reused only when its fingerprint (relaxation settings, material,
numerics, code) matches. run.py computes the same starts when they are missing.

    python experiments/tgv2d/relax.py --profile smoke [--results results/smoke]
"""
from lab.cli import profile_main
from lab.tgv2d_runs import relaxed_positions

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def options(ap):
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    exp = S.load(args.profile)
    for dx in exp.dx:
        relaxed_positions(S.STUDY, exp, dx, args.results, progress=not args.no_progress)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
