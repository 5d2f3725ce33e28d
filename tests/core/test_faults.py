"""No silent wrong results (issue 13), core side: every fault ends in a named error.

One test per fault: particles leaving a non-periodic domain (forward runs and differentiated
rollouts), unchecked or non-finite config values, degenerate resolutions and walls thinner than the
kernel support, runs too large for the memory, blow-ups diagnosed (step, particle, dt against its
limits) with the last good frame kept, a fixed dt above its limits reported before the run, and
config errors printed as one line naming the file, the profile the key is written in and the key.
All on smoke sizes (at most a few hundred particles, a few hundred steps).
"""
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import h5py
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import yaml

import sph
from sph import rollout, simulate
from lab import io
from sph.cases import ldc, tgv
from lab.cli import EXIT_CONFIG, EXIT_SIMULATION, main_guard
from lab.configtools import ConfigError, from_mapping, load_profile
from sph.errors import BlowUp, NeighborOverflow, ParticleEscaped, SimulationError
from sph.domain import Domain
from sph.lattice import cartesian
from sph.scene import Scene
from sph.checks import UnstableTimeStep
from sph.memory import InsufficientMemory
from sph.state import FLUID
from sph_test_helpers import copied_experiment

DX = 0.05
ROOT = Path(__file__).resolve().parents[2]


def thrown_block(speed=3.0, resting_block=False):
    """A 4 x 4 block near the top of an open (non-periodic, wall-less) unit box, thrown upwards;
    optionally a second block at rest near the bottom (the one a wrap-around would disturb)."""
    r = cartesian([0.4, 0.7], [0.6, 0.9], DX)
    u = np.tile([0.0, speed], (len(r), 1))
    if resting_block:
        r2 = cartesian([0.4, 0.05], [0.6, 0.25], DX)
        r, u = np.concatenate([r, r2]), np.concatenate([u, np.zeros_like(r2)])
    return Scene(name="thrown", dx=DX, domain=Domain(box=(1.0, 1.0), periodic=(False, False)),
                 material=sph.Material(eta=0.01, u_ref=speed), effects=sph.Effects(), r=r, u=u,
                 tag=np.full(len(r), FLUID, np.int32))


# -- 1. particles leaving the domain ---------------------------------------------------------------

def test_escape_stops_the_run_naming_particle_step_position_and_keeps_last_frame(tmp_path):
    solver = sph.build_solver(thrown_block(resting_block=True))
    state, nbrs = solver.init_fn()
    with io.TrajectoryWriter.create(tmp_path / "t.h5", solver.scene.tag, 2) as w:
        with pytest.raises(ParticleEscaped, match=r"fluid particle \d+ left the domain at step \d+ .*position \[") as e:
            simulate.run(solver, state, nbrs, t_end=1.0, write_every=20, writer=w, progress=False)
        _, ck_step, _ = w.load_checkpoint()
    err = e.value
    assert isinstance(err, RuntimeError) and err.particle is not None and err.step is not None
    assert err.position[1] >= 1.0 and err.particle < 16  # one of the thrown block, through the top
    assert "dimension 1" in str(err) and str(tmp_path / "t.h5") in str(err)
    assert ck_step < err.step <= ck_step + 20
    # the kept state is the last good one: every particle inside the box (no step with a particle
    # outside, which would interact with the block at the bottom through the wrapped search box)
    ck, _, _ = io.load_checkpoint(tmp_path / "t.h5")
    r = np.asarray(ck.r)
    assert np.all((r >= 0) & (r < 1.0))


def test_chunk_refuses_the_escaping_step_and_advance_names_it():
    """The guard works inside the scan: the chunk stops before the escaping step, with the last good
    state (no particle outside), and `advance` raises the diagnosis."""
    solver = sph.build_solver(thrown_block())
    state, nbrs = solver.init_fn()
    chunk = jax.jit(rollout.make_chunk(solver.step_fn, 400, guard=solver.guard))
    s, _, n_done, overflow = chunk(state, nbrs, 0, 400)
    assert not bool(overflow) and 0 < int(n_done) < 400
    assert np.all(np.asarray(s.r) < 1.0)
    with pytest.raises(ParticleEscaped, match=rf"at step {int(n_done) + 1} "):
        rollout.advance(chunk, solver.neighbors, state, nbrs, 0, 400)


def test_escape_in_a_differentiated_rollout_gives_no_gradient():
    solver = sph.build_solver(thrown_block())
    state, nbrs = solver.init_fn()
    n_steps = 300  # the block reaches the top (0.1 at speed 3) after ~150 steps of dt 0.0006
    # scan_rollout flags it (folded into its invalid flag; apart with split=True)
    _, _, invalid = jax.jit(lambda s, nb: rollout.scan_rollout(solver.step_fn, s, nb, n_steps))(state, nbrs)
    assert bool(invalid)
    _, _, overflow, refused = jax.jit(
        lambda s, nb: rollout.scan_rollout(solver.step_fn, s, nb, n_steps, split=True))(state, nbrs)
    assert bool(refused) and not bool(overflow)
    vg = rollout.value_and_grad_rollout(lambda s: jnp.sum(s.r[:, 1]), solver, n_steps)
    with pytest.raises(ParticleEscaped, match=r"value_and_grad_rollout: no gradient .*fluid particle \d+ left"):
        vg(jnp.asarray(solver.scene.r), nbrs)


def test_escape_check_is_free_in_periodic_domains_and_allows_walls():
    """Wall particles and periodic dimensions are never 'outside': a cavity and a TGV step on."""
    for scene in (ldc.scene(0.1, sph.Material(eta=0.1), sph.Effects(walls="no_slip")),
                  tgv.scene(0.1, sph.Material(eta=0.1), sph.Effects())):
        solver = sph.build_solver(scene)
        state, nbrs = solver.init_fn()
        assert not bool(jax.jit(solver.guard.reject)(state))
        res = simulate.run(solver, state, nbrs, t_end=20 * solver.dt, write_every=10, progress=False)
        assert res.n_steps == 20


# -- 2. every config value checked ------------------------------------------------------------------

NAN, INF = float("nan"), float("inf")


@pytest.mark.parametrize("cls,data,key", [
    (sph.Numerics, {"eta_limiter": NAN}, "eta_limiter"),
    (sph.Numerics, {"p_b_factor": NAN}, "p_b_factor"),
    (sph.Numerics, {"p_b_factor": -1.0}, "p_b_factor"),
    (sph.Numerics, {"p_bg_factor": NAN}, "p_bg_factor"),
    (sph.Numerics, {"p_bg_factor": -0.5}, "p_bg_factor"),
    (sph.Numerics, {"h_factor": INF}, "h_factor"),
    (sph.Numerics, {"dt": INF}, "dt"),
    (sph.Numerics, {"skin_factor": NAN}, "skin_factor"),
    (sph.Numerics, {"capacity_multiplier": INF}, "capacity_multiplier"),
    (sph.Material, {"u_ref": INF}, "u_ref"),
    (sph.Material, {"kappa": INF}, "kappa"),
    (sph.Material, {"eta": NAN}, "eta"),
    (sph.Effects, {"gravity": [NAN, 0.0]}, "gravity[0]"),
    (sph.Effects, {"artificial_viscosity": INF}, "artificial_viscosity"),
])
def test_non_finite_and_out_of_range_values_are_named(cls, data, key):
    for build in (lambda: from_mapping(cls, data, cls.__name__.lower()), lambda: cls(**data)):
        with pytest.raises(ConfigError, match=rf"{key.replace('[', '[[]')}: must be"):
            build()


def test_inf_can_be_allowed_per_field():
    from dataclasses import dataclass, field

    @dataclass(frozen=True)
    class C:
        limit: float = field(default=1.0, metadata={"allow_inf": True})

    assert from_mapping(C, {"limit": INF}).limit == INF
    with pytest.raises(ConfigError, match="limit: must be a finite number, got nan"):
        from_mapping(C, {"limit": NAN})


def _load(folder):
    """The folder's settings loader `load(profile, overrides=...)`: the protocol's (lab.experiment) for a
    folder with a study.py, else its settings.py's."""
    import functools
    import importlib

    if (ROOT / folder / "study.py").exists():
        from lab.experiment import load_settings

        return functools.partial(load_settings, ROOT / folder)
    return importlib.import_module(f"{folder.replace('/', '.')}.settings").load


@pytest.mark.parametrize("folder,overrides,key", [
    ("experiments/tgv2d", {"t_end": INF}, "t_end"),
    ("experiments/tgv2d", {"material": {"eta": 0.0}}, "material.eta"),
    ("experiments/tgv2d", {"material": {"u_ref": INF}}, "material.u_ref"),
    ("experiments/tgv2d", {"numerics": {"h_factor": INF}}, "numerics.h_factor"),
    ("experiments/tgv2d", {"numerics": {"p_bg_factor": NAN}}, "numerics.p_bg_factor"),
    ("experiments/tgv2d", {"numerics": {"eta_limiter": NAN}}, "numerics.eta_limiter"),
    ("experiments/ldc2d", {"material": {"eta": 0.0}}, "material.eta"),
    ("experiments/dambreak2d", {"frame_dt": INF}, "frame_dt"),
    ("experiments/dambreak2d", {"effects": {"gravity": [NAN, -1.0]}}, "effects.gravity[0]"),
    ("experiments/thermal", {"channel": {"material": {"kappa": INF}}}, "channel.material.kappa"),
    ("experiments/thermal", {"channel": {"material": {"eta": 0.0}}}, "channel.material.eta"),
    ("inverse", {"u0": [NAN, -0.5]}, "u0[0]"),
])
def test_experiment_settings_name_the_key(folder, overrides, key):
    load = _load(folder)
    with pytest.raises(ConfigError) as e:
        load("smoke", overrides=overrides)
    assert key in str(e.value) and "config.yaml" in str(e.value), str(e.value)


def test_stability_case_values_are_checked():
    load = _load("experiments/stability")
    with pytest.raises(ConfigError, match=r"cases\.heat_sine\.T0: must be a finite number"):
        load("smoke", overrides={"cases": {"heat_sine": {"T0": INF}}})


# -- 6. the dam break's heat flag in its own terms ----------------------------------------------------

def test_dambreak_heat_names_its_fluid_section():
    load = _load("experiments/dambreak2d")
    with pytest.raises(ConfigError, match=r"effects\.heat: .*`fluid` section") as e:
        load("smoke", overrides={"effects": {"heat": True}})
    assert "material.kappa" not in str(e.value)


# -- 3. degenerate resolutions and memory -------------------------------------------------------------

MAT = sph.Material(eta=0.01)


@pytest.mark.parametrize("dx", [1.0, 0.5, 0.25, 0.2])
def test_periodic_box_shorter_than_twice_the_support_is_refused(dx):
    with pytest.raises(ConfigError, match=r"scene tgv2d: dx = .* too coarse: the periodic side 0 .*own periodic image"):
        sph.build_solver(tgv.scene(dx, MAT, sph.Effects()))


def test_smallest_periodic_box_allowed_is_exact():
    """The limit is L = 2 cutoff (6 particles across for the quintic kernel at h = dx): there the
    summation density equals the sum over all periodic images."""
    from sph.kernels import make_kernel

    dx = 1.0 / 6
    r = (cartesian([0, 0], [1, 1], dx) + np.random.default_rng(0).normal(scale=0.1 * dx, size=(36, 2))) % 1.0
    solver = sph.build_solver(tgv.scene(dx, MAT, sph.Effects(), r=r))
    state, _ = solver.init_fn()
    k = make_kernel("quintic", dx, 2)
    shifts = np.array([(a, b) for a in range(-2, 3) for b in range(-2, 3)], float)
    d = np.linalg.norm(r[:, None, None, :] - r[None, :, None, :] - shifts[None, None], axis=-1)
    exact = dx * dx * np.asarray(k.w(d)).sum(axis=(1, 2))
    np.testing.assert_allclose(np.asarray(state.rho), exact, rtol=1e-12)


@pytest.mark.parametrize("dx", [1.0, 0.5])
def test_cavity_coarser_than_the_support_is_refused(dx):
    with pytest.raises(ConfigError, match=r"scene ldc2d: dx = .* too coarse: the walled box is [0-9.]+ wide in dimension 0"):
        sph.build_solver(ldc.scene(dx, MAT, sph.Effects(walls="no_slip")))


@pytest.mark.parametrize("layers", [1, 2])
def test_walls_thinner_than_the_support_are_refused(layers):
    with pytest.raises(ConfigError, match=rf"walls are thinner than the kernel support.*about {layers} layers.*"
                                          r"at least 3 wall layers"):
        sph.build_solver(ldc.scene(0.1, MAT, sph.Effects(walls="no_slip"), layers=layers))
    # a kernel with a shorter support needs fewer layers (Wendland C2: 2 h)
    if layers == 2:
        sph.build_solver(ldc.scene(0.1, MAT, sph.Effects(walls="no_slip"), layers=2),
                         sph.Numerics(kernel="wendland_c2"))


def test_huge_scene_is_refused_before_allocating():
    with pytest.raises(InsufficientMemory, match=r"100,000,000 particles.*GiB.*use a larger dx") as e:
        tgv.scene(1e-4, MAT, sph.Effects())
    assert isinstance(e.value, MemoryError) and isinstance(e.value, ConfigError)


def test_build_solver_estimates_memory(monkeypatch):
    import sph.memory as S

    monkeypatch.setattr(S, "available_memory", lambda: (10**6, "available host memory"))
    with pytest.raises(InsufficientMemory, match=r"400 particles \(dx = 0.05\) with \d+ neighbour slots .* need at least"):
        sph.build_solver(tgv.scene(0.05, MAT, sph.Effects()))


# -- 4. blow-ups diagnosed, the last good frame kept ---------------------------------------------------

def test_fixed_dt_above_its_limit_is_reported_at_build():
    with pytest.warns(UnstableTimeStep, match=r"numerics\.dt = 0\.025 exceeds the convective time-step limit .* by \d"):
        sph.build_solver(tgv.scene(0.1, MAT, sph.Effects()), sph.Numerics(dt=0.025))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sph.build_solver(tgv.scene(0.1, MAT, sph.Effects()), sph.Numerics(dt=0.001))


def test_blow_up_without_u_limit_names_particle_and_dt_and_keeps_last_frame(tmp_path):
    """Riemann SPH at 11x the CFL time step: the default speed limit (c_ref) stops it at the first
    bad step, naming the particle and dt against its limits; the checkpoint holds the last good frame."""
    scene = tgv.scene(0.1, sph.Material(), sph.Effects(riemann=True, density_evolution=True))
    with pytest.warns(UnstableTimeStep):
        solver = sph.build_solver(scene, sph.Numerics(dt=0.025))
    state, nbrs = solver.init_fn()
    with io.TrajectoryWriter.create(tmp_path / "t.h5", scene.tag, 2) as w:
        with pytest.raises(BlowUp, match=r"blew up at step \d+ \(t=[0-9.]+\): particle \d+ .*dt = 0\.025 "
                                         r"\(numerics\.dt \(fixed\)\) is [0-9.]+x the convective limit") as e:
            simulate.run(solver, state, nbrs, t_end=50 * solver.dt, write_every=5, writer=w, progress=False)
        _, ck_step, _ = w.load_checkpoint()
    assert ck_step < e.value.step <= ck_step + 5
    assert "kept in the checkpoint" in str(e.value)
    assert io.trajectory_status(tmp_path / "t.h5")["n_frames"] == ck_step // 5 + 1


def test_repeated_overflow_names_a_particle_and_dt():
    """A list that keeps overflowing (here: no re-allocation allowed) is diagnosed by the guard."""
    r = tgv.cartesian([0, 0], [1, 1], 0.1) + np.random.default_rng(1).normal(scale=0.02, size=(100, 2))
    scene = tgv.scene(0.1, MAT, sph.Effects(), r=np.mod(r, 1.0))
    solver = sph.build_solver(scene)
    state, _ = solver.init_fn()
    from sph.neighbors import make_neighbor_search

    tight = make_neighbor_search(scene.domain, solver.neighbors.cutoff, solver.neighbors.skin, 1.0)
    sparse = tight.allocate(jnp.asarray(tgv.cartesian([0, 0], [1, 1], 0.1)))  # too few slots for r
    with pytest.raises(NeighborOverflow, match=r"neighbour list kept overflowing at step 1 .*particle \d+ has the "
                                               r"most neighbours .*dt = "):
        simulate.run(solver, state, sparse, t_end=10 * solver.dt, write_every=5, progress=False,
                     max_reallocations=0)


def test_overflow_is_still_recovered_with_the_guard():
    """The guard does not change a run: overflow re-allocation and a guarded chunk give the same
    state as an unguarded rollout with an ample list."""
    r = np.mod(tgv.cartesian([0, 0], [1, 1], 0.1) + np.random.default_rng(1).normal(scale=0.02, size=(100, 2)), 1.0)
    solver = sph.build_solver(tgv.scene(0.1, MAT, sph.Effects(), r=r))
    state, nbrs = solver.init_fn()
    plain = jax.jit(rollout.make_chunk(solver.step_fn, 20))
    ref, _, _ = rollout.advance(plain, solver.neighbors, state, nbrs, 0, 20)
    from sph.neighbors import make_neighbor_search

    tight = make_neighbor_search(solver.scene.domain, solver.neighbors.cutoff, solver.neighbors.skin, 1.0)
    sparse = tight.allocate(jnp.asarray(tgv.cartesian([0, 0], [1, 1], 0.1)))
    res = simulate.run(solver, state, sparse, t_end=20 * solver.dt, write_every=10, progress=False)
    assert res.n_reallocations >= 1
    np.testing.assert_allclose(np.asarray(res.state.u), np.asarray(ref.u), rtol=0, atol=1e-12)


def test_relaxation_with_a_too_large_dt_names_dt():
    from sph.relax import Relaxation, relax

    scene = tgv.scene(0.1, MAT, sph.Effects())
    with pytest.warns(UnstableTimeStep):
        with pytest.raises(RuntimeError, match=r"near step \d+: particles are clumping.*check numerics\.dt / numerics\.cfl"):
            relax(scene, sph.Numerics(dt=0.05), Relaxation(steps=100, quench_every=20), progress=False)


# -- 5. config errors as one line ---------------------------------------------------------------------

@pytest.fixture
def two_profiles(tmp_path):
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump({"profiles": {
        "paper": {"numerics": {"cfl": 2.0, "dtype": "float64"}},
        "smoke": {"inherit": "paper", "numerics": {"dtype": "float32"}},
    }}))
    return path


def _run_config(path, profile="smoke", overrides=None):
    from dataclasses import dataclass, field

    @dataclass(frozen=True)
    class Run:
        numerics: sph.Numerics = field(default_factory=sph.Numerics)

    return load_profile(Run, path, profile, overrides)


def test_error_names_the_profile_the_key_is_written_in(two_profiles):
    with pytest.raises(ConfigError) as e:
        _run_config(two_profiles)
    msg = str(e.value)
    assert msg.startswith(f"{two_profiles}: profiles.paper.numerics.cfl: must be in (0, 1]"), msg
    assert "profile smoke inherits it from paper" in msg
    assert (e.value.file, e.value.profile, e.value.origin, e.value.key) == (str(two_profiles), "smoke", "paper",
                                                                            "numerics.cfl")
    # the key written in the requested profile itself is named there
    with pytest.raises(ConfigError, match=r"config\.yaml: profiles\.paper\.numerics\.cfl: must be in \(0, 1\], got 2"):
        _run_config(two_profiles, profile="paper")


def test_override_is_named_as_command_line(two_profiles):
    with pytest.raises(ConfigError, match=r"config\.yaml: numerics\.cfl: must be .*\(set on the command line over profile smoke\)"):
        _run_config(two_profiles, overrides={"numerics": {"cfl": 3.0}})


def test_main_guard_prints_one_line_and_exits_2(two_profiles, capsys):
    with pytest.raises(SystemExit) as e:
        main_guard(_run_config, two_profiles)
    assert e.value.code == EXIT_CONFIG
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert str(two_profiles) in err and "profiles.paper.numerics.cfl" in err


def test_main_guard_prints_simulation_errors_and_exits_3(capsys):
    def boom():
        raise SimulationError("simulation blew up at step 3 (t=0.3): particle 7 ...")

    with pytest.raises(SystemExit) as e:
        main_guard(boom)
    assert e.value.code == EXIT_SIMULATION
    assert "particle 7" in capsys.readouterr().err
    assert main_guard(lambda x: x + 1, 1) == 2


# -- interrupted runs: SIGINT and SIGKILL, then resume to the uninterrupted numbers ----------------

def _study(tmp_path):
    """A copy of tgv2d (a folder is a template) whose smoke profile is one small, long run: 100
    particles, ~22000 steps, a frame every 220 steps (several seconds of compute even with the
    faster solver, so that a signal sent at 1/4 or 1/2 lands mid-run, not during the process's exit:
    at ~8800 steps a CI run once finished before its SIGINT took effect and exited 0)."""
    return copied_experiment("tgv2d", tmp_path / "study", dx=[0.1], t_end=50.0, frames=100, eval_times=[1.0],
                             methods=[{"name": "tvf", "effects": {"tvf": True}}],
                             relaxation={"steps": 20, "quench_every": 10})


def _checkpoint_step(path) -> int:
    """The writer's checkpoint step, read while another process writes the file (no file lock)."""
    try:
        with h5py.File(path, "r", locking=False) as f:
            return int(f["00000/checkpoint"].attrs["step"])
    except Exception:  # not created yet, or caught mid-write
        return -1


def _interrupt(cmd, traj, min_step: int, sig, timeout: float = 300) -> int:
    """Start `cmd`, send it `sig` once the checkpoint in `traj` has reached `min_step`; its exit code."""
    # SIGINT back to its default in the child: a shell without job control starts background jobs
    # with SIGINT ignored (POSIX), the ignore is inherited by pytest and its children, and a Python
    # started with SIGINT ignored never turns it into KeyboardInterrupt - a clean-clone check started
    # with `cmd &` ran this run to completion, exit 0. A user's Ctrl-C in a terminal always has it.
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    t0 = time.time()
    while proc.poll() is None and _checkpoint_step(traj) < min_step and time.time() - t0 < timeout:
        time.sleep(0.02)
    assert proc.poll() is None, f"the run ended before it could be interrupted: {proc.stderr.read()[-2000:]}"
    proc.send_signal(sig)
    proc.wait(timeout=60)
    return proc.returncode


def test_sigint_and_sigkill_resume_to_the_uninterrupted_numbers(tmp_path):
    """A run stopped by Ctrl-C, then by SIGKILL, keeps what it wrote; calling it again continues from
    its last frame to the same trajectory as a run never interrupted (float64: to round-off)."""
    study = _study(tmp_path)

    def cmd(res):
        return [sys.executable, "-m", "lab.experiment", str(study), "--profile", "smoke", "--results", str(res),
                "--no-progress"]

    ref, out = tmp_path / "ref", tmp_path / "out"
    subprocess.run(cmd(ref), check=True, capture_output=True, text=True)
    a = io.read_trajectory(ref / "study" / "tvf_dx0.1" / "traj.h5")
    n_steps = int(a["attrs"]["n_steps"])
    assert n_steps > 5000

    traj = out / "study" / "tvf_dx0.1" / "traj.h5"
    assert _interrupt(cmd(out), traj, n_steps // 4, signal.SIGINT) != 0
    st = io.trajectory_status(traj)
    assert st["exists"] and not st["complete"] and n_steps // 4 <= st["checkpoint_step"] < n_steps

    assert _interrupt(cmd(out), traj, n_steps // 2, signal.SIGKILL) == -signal.SIGKILL
    assert not io.trajectory_status(traj)["complete"]

    done = subprocess.run(cmd(out), check=True, capture_output=True, text=True)
    assert "resuming at step" in done.stdout
    b = io.read_trajectory(traj)
    np.testing.assert_array_equal(a["step"], b["step"])
    np.testing.assert_allclose(b["position"], a["position"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b["e_kin"], a["e_kin"], rtol=1e-12)
