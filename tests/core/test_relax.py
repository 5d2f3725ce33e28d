"""sph/relax.py: the relaxation is geometric. A scene's gravity drives no flow while its particles
spread (in a periodic box, gravity alone would carry the whole fluid by g t^2 / 2), and a very
viscous scene relaxes at the convective time step when Relaxation.eta asks for a smaller viscosity,
instead of under its viscous limit cfl h^2 rho_ref / eta (sph/timestep.py)."""
import numpy as np
import pytest

import sph
from sph.cases import tgv
from sph.relax import Relaxation, relax

pytestmark = pytest.mark.compile_bound  # its programs run a few steps: XLA -O0 (conftest._compile_bound)

DX = 0.1
MAT = sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0)


def _jittered(seed=3):
    r = tgv.cartesian([0.0, 0.0], [1.0, 1.0], DX) + np.random.default_rng(seed).normal(scale=0.1 * DX, size=(100, 2))
    return np.mod(r, 1.0)


def _mean_shift(r0, r1):
    d = r1 - r0
    d -= np.round(d)  # minimum image in the unit box
    return d.mean(axis=0)


def test_gravity_drives_no_flow_while_the_particles_spread():
    r0 = _jittered()
    g = (0.0, -5.0)
    scene = tgv.scene(DX, MAT, sph.Effects(gravity=g), r=r0)
    steps = 200
    r, info = relax(scene, sph.Numerics(), Relaxation(steps=steps, quench_every=20), progress=False)
    t = steps * info["dt"]
    shift = _mean_shift(r0, r)
    # gravity left on would shift every particle by about g t^2 / 2 between quenches (20 steps each):
    # 10 quench intervals of 0.5 g (20 dt)^2
    by_gravity = 10 * 0.5 * 5.0 * (20 * info["dt"]) ** 2
    assert by_gravity > 1e-4 and t > 0
    assert abs(shift[1]) < 0.01 * by_gravity, (shift, by_gravity)
    # and the particles did spread: the closest pair moved apart
    def closest(x):
        d = x[:, None] - x[None]
        d -= np.round(d)
        dist = np.sqrt((d**2).sum(-1)) + np.eye(len(x))
        return dist.min()
    assert closest(r) > closest(r0)


def test_a_viscous_scene_relaxes_at_the_convective_step_with_a_smaller_eta():
    viscous = sph.Material(rho_ref=1.0, eta=100.0, u_ref=1.0)
    scene = tgv.scene(DX, viscous, sph.Effects(), r=_jittered())
    numerics = sph.Numerics()
    _, own = relax(scene, numerics, Relaxation(steps=10, quench_every=5), progress=False)
    _, low = relax(scene, numerics, Relaxation(steps=10, quench_every=5, eta=0.01), progress=False)
    h = numerics.h_factor * DX
    assert own["dt"] == pytest.approx(numerics.cfl * h**2 * 1.0 / 100.0)   # the viscous limit
    assert low["dt"] > 50 * own["dt"]                                      # the convective one
    c_ref = numerics.c_ref_factor * viscous.u_ref
    assert low["dt"] == pytest.approx(numerics.cfl * h / (c_ref + viscous.u_ref))


def test_a_negative_relaxation_viscosity_is_refused_by_name():
    with pytest.raises(sph.ConfigError, match=r"relaxation\.eta"):
        Relaxation(eta=-1.0)
