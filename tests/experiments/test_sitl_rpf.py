"""The reverse Poiseuille flow scene (sph/cases/rpf.py) and the dataset's force.py: the force has
the right sign at every particle (the authors' solver gave all particles one force), and the
analytical start-up profile tends to the steady one; experiments/sitl's scene is the one its dataset
was made from."""
import importlib.util
import json
from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import sph
from sph.cases import rpf
from sitl import generate
from sitl import settings as S


def _expected_sign(r):
    return np.where(r[:, 1] < 1.0, 1.0, -1.0)


def test_rpf_force_has_the_right_sign_per_particle():
    """Every particle of a 1 x 2 scene gets +g below y = 1 and -g above, through the solver's
    acceleration (du/dt with the force minus without equals the per-particle force)."""
    dx = 0.1
    mat = sph.Material(eta=0.1)
    sc = rpf.scene(dx, mat, sph.Effects(), g=1.0)
    f = np.asarray(sc.body_force(jnp.asarray(sc.r)))
    sign = _expected_sign(sc.r)
    assert (sign > 0).sum() == (sign < 0).sum() == sc.n // 2
    np.testing.assert_array_equal(f[:, 0], sign)
    np.testing.assert_array_equal(f[:, 1], 0.0)
    with_force = sph.build_solver(sc, sph.Numerics(dtype="float64")).init_fn()[0].dudt
    no_force = sph.build_solver(rpf.scene(dx, mat, sph.Effects(), g=0.0), sph.Numerics(dtype="float64")).init_fn()[0].dudt
    np.testing.assert_allclose(np.asarray(with_force - no_force), f, atol=1e-12)


def test_force_py_is_per_particle(tmp_path):
    """The dataset's force.py maps ONE position (dim,) to its force, as LagrangeBench's features
    vmap it; applied to each particle it gives the sign of its half."""
    (tmp_path / "force.py").write_text(generate.FORCE_PY.format(g=1.0, split=1.0))
    spec = importlib.util.spec_from_file_location("force_module", tmp_path / "force.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    r = np.array([[0.3, 0.2], [0.7, 0.99], [0.1, 1.0], [0.5, 1.7]])
    for ri, s in zip(r, _expected_sign(r)):
        out = np.asarray(mod.force_fn(jnp.asarray(ri)))
        assert out.shape == (2,)
        np.testing.assert_array_equal(out, [s, 0.0])
    import jax
    np.testing.assert_array_equal(np.asarray(jax.vmap(mod.force_fn)(jnp.asarray(r)))[:, 0], _expected_sign(r))


def test_startup_profile_tends_to_the_steady_one():
    g, nu = 1.0, 0.1
    y = np.linspace(0.0, 2.0, 81)
    steady = rpf.u_steady(y, g, nu)
    assert rpf.u_steady(0.5, g, nu) == pytest.approx(g / (8 * nu))
    assert rpf.u_steady(1.5, g, nu) == pytest.approx(-g / (8 * nu))
    np.testing.assert_allclose(rpf.u_startup(y, 50.0, g, nu), steady, atol=1e-5)
    np.testing.assert_allclose(rpf.u_startup(y, 0.0, g, nu), 0.0, atol=1e-12)
    # early on the fluid accelerates at g away from the split: u ~ g t in the bulk
    assert rpf.u_startup(np.array([0.5]), 0.01, g, nu)[0] == pytest.approx(0.01, rel=1e-3)


def test_settings_validate_profiles():
    for p in ("smoke", "cpu", "paper"):
        exp = S.load(p)
        assert exp.models == ("solver", "gns", "sitl")
    with pytest.raises(sph.ConfigError, match="data.frames"):
        S.load("smoke", overrides={"data": {"frames": [40, 44]}})
    with pytest.raises(sph.ConfigError, match="stpes"):
        S.load("smoke", overrides={"train": {"stpes": 3}})


def test_metadata_and_stats(tmp_path):
    """metadata.json keys LagrangeBench reads, frame interval dt * write_every, and the statistics
    in per-frame displacement units across the periodic boundary, on motion with NON-ZERO
    accelerations: x_i(t) = x_i0 + v_i t + a_i t^2 / 2 (t in frames), wrapped into the box, so that
    the per-frame velocity of frame pair (t, t+1) is v_i + a_i (t + 1/2) and the acceleration a_i
    exactly; the expected statistics are computed from these formulas, not from the positions."""
    exp = S.load("smoke", overrides={"data": {"frames": [8, 8, 8], "profile_window": 3},
                                     "eval": {"n_rollout_steps": 5, "n_trajs": 1}, "fig3": {"stamps": [0, 5], "steps": 5},
                                     "train": {"eval_n_trajs": 1}})
    n = exp.data.n_particles
    rng = np.random.default_rng(0)
    box = np.array([1.0, 2.0])
    base = rng.uniform(0, 1, (n, 2)) * box
    v = np.stack([rng.normal(0.02, 0.01, n), rng.normal(0.0, 0.005, n)], axis=1)
    a = np.stack([rng.normal(3e-3, 2e-3, n), rng.normal(-1e-3, 1e-3, n)], axis=1)
    t = np.arange(24, dtype=np.float64)[:, None, None]
    pos = np.mod(base + v * t + 0.5 * a * t**2, box).astype(np.float32)[None]   # crosses the boundary
    assert (np.abs(np.diff(pos[0, :8], axis=0)) > 0.5).any()                      # some particles wrap
    info = {"dt": 0.002, "steps": 100}
    meta = generate.write(tmp_path, exp, pos, np.arange(24) * 0.02, info)
    assert json.loads((tmp_path / "metadata.json").read_text()) == meta
    assert meta["dt"] * meta["write_every"] == pytest.approx(0.02)
    assert meta["periodic_boundary_conditions"] == [True, True]
    assert meta["bounds"] == [[0.0, 1.0], [0.0, 2.0]]
    assert meta["default_connectivity_radius"] == pytest.approx(1.45 * exp.data.dx)
    assert meta["num_particles_max"] == n
    # the 8 training frames: 7 velocities (t = 0..6), 6 accelerations per particle
    vel = v[None] + a[None] * (np.arange(7)[:, None, None] + 0.5)
    acc = np.broadcast_to(a, (6, n, 2))
    # float32 positions (~1e-7 of the box) limit the stored differences to ~1e-7 absolute
    np.testing.assert_allclose(meta["vel_mean"], vel.reshape(-1, 2).mean(0), rtol=0, atol=1e-6)
    np.testing.assert_allclose(meta["vel_std"], vel.reshape(-1, 2).std(0), rtol=1e-3)
    np.testing.assert_allclose(meta["acc_mean"], acc.reshape(-1, 2).mean(0), rtol=0, atol=2e-6)
    np.testing.assert_allclose(meta["acc_std"], acc.reshape(-1, 2).std(0), rtol=2e-2)
    assert min(np.abs(meta["acc_mean"])) > 5e-4 and min(meta["acc_std"]) > 5e-4   # really non-zero


def test_settings_are_the_papers():
    """Paper App. B.2: lr 1e-3; training noise 1e-3 for GNS and 1e-5 for SitL, in every profile;
    checkpoint selection on >= 25 validation windows and tests on every seed where data allow it."""
    for p in ("smoke", "cpu", "paper"):
        t = S.load(p).train
        assert t.lr_start == 1e-3 and t.noise_std == 1e-3 and t.sitl_noise_std == 1e-5, (p, t)
        assert t.noise("gns") == 1e-3 and t.noise("sitl") == t.noise("solver") == 1e-5
    for p in ("cpu", "paper"):
        exp = S.load(p)
        # every seed tested alike: all windows, or as many of each (round-robin over the seeds)
        ev, seeds = exp.eval.n_trajs, exp.data.seeds
        assert exp.train.eval_n_trajs >= 25 and (ev == -1 or (ev >= seeds and ev % seeds == 0)), p
    assert S.load("cpu").data.seeds >= 4   # test windows from at least 4 independent trajectories (issue 39)
    assert 1e-5 in S.load("cpu").study.noise and 3e-4 in S.load("cpu").study.noise
    with pytest.raises(sph.ConfigError, match=r"study\.substeps\[0\]: L = 3 does not divide data\.write_every = 20"):
        S.load("cpu", overrides={"study": {"substeps": [3]}})
    with pytest.raises(sph.ConfigError, match=r"study\.authors_force_data\.dxx"):
        S.load("cpu", overrides={"study": {"authors_force_data": {"dxx": 0.1}}})
    with pytest.raises(sph.ConfigError, match=r"train\.eval_n_trajs: 60 exceeds the 48 windows"):
        S.load("cpu", overrides={"train": {"eval_n_trajs": 60}})
    # a GNS with LagrangeBench's 6 input positions, alone; SitL and the solver start from one velocity
    assert S.load("cpu", overrides={"model": {"input_seq_length": 6}, "models": ["gns"]}).model.input_seq_length == 6
    with pytest.raises(sph.ConfigError, match=r"model\.input_seq_length: 6 positions, but solver and sitl"):
        S.load("cpu", overrides={"model": {"input_seq_length": 6}})
    af = S.authors_force_experiment(S.load("cpu")).data
    assert (af.dx, af.dt * af.write_every) == (0.025, pytest.approx(0.01))   # the paper's resolution and interval


# LagrangeBench 0.2.0's default pushforward schedule (lagrangebench/defaults.py) for its 500k steps
LB_PUSHFORWARD = {"steps": [-1, 20000, 300000, 400000], "unrolls": [0, 1, 2, 3], "probs": [18, 2, 1, 1]}


def test_pushforward_is_off_as_in_the_paper_and_a_study_row_of_its_own():
    """The paper trains without pushforward (App. B.2): every profile's training has none (one stage,
    no unroll). The study's pushforward runs use LagrangeBench's default schedule (paper profile) and
    the same schedule scaled to the cpu profile's 3000 steps; a bad schedule names its key."""
    for p in ("smoke", "cpu", "paper"):
        t = S.load(p).train
        assert (t.pushforward_steps, t.pushforward_unrolls, t.pushforward_probs) == ((-1,), (0,), (1.0,)), p
        assert t.max_unroll == 0
    paper, cpu = S.load("paper"), S.load("cpu")
    assert {k: paper.study.pushforward[k] for k in LB_PUSHFORWARD} == LB_PUSHFORWARD
    scale = cpu.train.step_max / 500_000
    assert cpu.study.pushforward["steps"][1:] == [round(s * scale) for s in LB_PUSHFORWARD["steps"][1:]]
    assert cpu.study.pushforward["unrolls"] == LB_PUSHFORWARD["unrolls"]
    assert cpu.study.pushforward["substeps"] == [2]            # where the solver alone blows up (M = 10)
    run = S.load("cpu", overrides={"model": {"substeps": 2}, "train": {
        "pushforward_steps": [-1, 120], "pushforward_unrolls": [0, 3], "pushforward_probs": [1, 1]}}).train
    assert run.max_unroll == 3 and run.pushforward_steps == (-1, 120)
    with pytest.raises(sph.ConfigError, match=r"train\.pushforward_steps: .*got 2, 1, 2"):
        S.load("cpu", overrides={"train": {"pushforward_steps": [-1, 5], "pushforward_unrolls": [0],
                                           "pushforward_probs": [1, 1]}})
    with pytest.raises(sph.ConfigError, match=r"study\.pushforward\.steps: must start below 0"):
        S.load("cpu", overrides={"study": {"pushforward": {"steps": [0, 5, 6, 7]}}})
    with pytest.raises(sph.ConfigError, match=r"study\.pushforward\.unrolls: must be >= 0"):
        S.load("cpu", overrides={"study": {"pushforward": {"unrolls": [0, -1, 2, 3]}}})
    with pytest.raises(sph.ConfigError, match=r"study\.pushforward\.substeps\[0\]: L = 4 has no solver-alone run"):
        S.load("cpu", overrides={"study": {"pushforward": {"substeps": [4]}}})


def test_the_sitl_folders_scene_is_the_one_its_dataset_was_made_from(sitl_smoke_dataset, tmp_path):
    """experiments/sitl's `scene(run)` (the flow every model learns) against the smoke dataset's own
    metadata, written by sitl/generate.py: particle count, spacing, time step, viscosity, density,
    kernel, background pressure and the body force's magnitude."""
    from lab.experiment import Experiment

    exp = Experiment(Path(S.__file__).resolve().parents[1] / "experiments" / "sitl", "smoke", tmp_path)
    meta = json.loads((Path(sitl_smoke_dataset) / "metadata.json").read_text())
    for run in exp.runs:
        scene, numerics = exp.study.scene(run)
        assert scene.n == meta["num_particles_max"] and scene.dx == pytest.approx(meta["dx"])
        assert numerics.dt == pytest.approx(meta["dt"]) and numerics.kernel == meta["kernel"]
        assert numerics.p_bg_factor == pytest.approx(meta["p_bg_factor"])
        assert scene.material.eta / scene.material.rho_ref == pytest.approx(meta["viscosity"])
        assert scene.material.rho_ref == pytest.approx(meta["rho_ref"])
        force = np.asarray(scene.body_force(jnp.asarray(scene.r)))
        assert np.abs(force[:, 0]).max() == pytest.approx(meta["g_ext_magnitude"]) and not force[:, 1].any()
