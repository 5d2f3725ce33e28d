"""The sharded step (sph.parallel, issue 40) equals the single-device step, by particle id, to round-off.

The equality runs need several XLA devices, which on a CPU exist only if
XLA_FLAGS=--xla_force_host_platform_device_count=D is set before jax is imported; so they run in a
child process (this file run as a script, `python tests/core/test_parallel.py CASE...`), which
leaves the devices of every other test module of the worker as they are. One child runs all cases
(one import, one start of the 4 host devices) and prints a JSON line; each test checks its case.

Default matrix (nearly all of its time is compilation), 200 steps each: TGV 2D with D = 2 (periodic
cut axis, both neighbours the same device), the dam break with D = 4 (free surface, Riemann SPH with
free-slip walls, closed cut axis, two slabs start with walls only, migration, a buffer
re-allocation), the heated channel with D = 4 (periodic + no-slip walls + heat, interior slabs), the
gradient of Fig. 1 (d E_kin / d r0 of every particle, through a 10-step TGV rollout) with D = 4; and, in two more children,
the cavity (walls, moving lid) on 2 processes x 1 CPU device on localhost (`jax.distributed.initialize`,
gloo). Every run with D > 1 also checks the refusal of a particle that crosses more than a slab in one
step. SPH_TEST_PARALLEL_FULL=1: every case with D = 2 and 4, and TGV 3D (16^3, 10 steps).
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

STEPS = 200
TOL = 1e-10
"""Largest |sharded - single| / max(1, max |single|) of any field: round-off (measured ~1e-12)."""

FULL = os.environ.get("SPH_TEST_PARALLEL_FULL", "0") == "1"
MATRIX = ([f"{c}:{d}" for c in ("tgv2d", "ldc", "dambreak", "channel", "tgv3d") for d in (2, 4)] + ["grad:2", "grad:4"]
          if FULL else ["tgv2d:2", "dambreak:4", "channel:4", "grad:4"])
TWO_PROCESSES = "ldc:2:50"
"""The case of the 2-process test (the cavity: walls, a moving lid, a closed cut axis), 50 steps: over
gloo every one of a step's dozen collectives is a round trip through localhost TCP."""


# ------------------------------------------------------------------------------------------------
# in this process: what needs no devices
# ------------------------------------------------------------------------------------------------

def test_decomposition_refuses_a_slab_narrower_than_the_halo_naming_the_largest_d():
    from sph import ConfigError, Domain
    from sph.parallel import decompose

    dom = Domain(box=(1.0, 0.5), periodic=(False, False))
    dec = decompose(dom, 0.1, 10)
    assert dec.axis == 0 and dec.width == pytest.approx(0.1)
    with pytest.raises(ConfigError, match=r"largest D that works is 10"):
        decompose(dom, 0.1, 11)
    # two slabs on a periodic axis (both neighbours one device) need only one halo width each
    assert decompose(Domain(box=(1.0, 1.0), periodic=(True, True)), 0.3, 2).width == pytest.approx(0.5)
    with pytest.raises(ConfigError, match=r"narrower than the halo width.*largest D that works is 3"):
        decompose(Domain(box=(1.0, 1.0), periodic=(True, True)), 0.3, 4)
    with pytest.raises(ConfigError, match="devices: must be a whole number"):
        decompose(dom, 0.1, 0)


def test_exchange_plan_sends_only_what_a_later_pass_reads():
    import sph
    from sph.cases import ldc, tgv
    from sph.parallel import ExchangePlan

    tvf = sph.build_solver(tgv.scene(0.05, tgv.material(100), tgv.METHODS["tvf"]), tgv.NUMERICS)
    plan = ExchangePlan.of(tvf.passes)
    assert set(plan.initial) == {"r", "mass", "u", "v"}
    assert plan.before == ((), (), ("rho", "p"))          # density, pressure (pointwise), forces
    sc, nu = ldc.setup(0.05, 100, "riemann")
    plan = ExchangePlan.of(sph.build_solver(sc, nu).passes)
    assert {"tag", "normal"} <= set(plan.initial)         # Riemann walls read j.wall and j.normal
    assert "u_visc" in plan.before[-1] and "u" not in plan.before[-1]


def test_a_launch_with_another_process_count_is_refused():
    import sph
    from sph.cases import tgv
    from sph.parallel import build_sharded

    solver = sph.build_solver(tgv.scene(0.05, tgv.material(100), tgv.METHODS["sph"]), tgv.NUMERICS)
    with pytest.raises(sph.ConfigError, match=r"configured for 2 process\(es\) but 1 were launched"):
        build_sharded(solver, 1, processes=2)
    with pytest.raises(ValueError, match="xla_force_host_platform_device_count"):
        build_sharded(solver, 5)          # 5 slabs fit the box, 1 device here


def test_an_overflow_that_persists_after_reallocation_is_refused(monkeypatch):
    """advance re-lays the particles out with larger buffers at each overflow, and refuses after
    max_reallocations (a stand-in chunk that always overflows its halo; one device, this process)."""
    import sph
    from sph.cases import tgv
    from sph.parallel import HaloOverflow, build_sharded
    from sph.parallel import driver

    solver = sph.build_solver(tgv.scene(0.1, tgv.material(100), tgv.METHODS["sph"]), tgv.NUMERICS)
    state, _ = solver.init_fn()
    sharded = build_sharded(solver, 1)
    shard, caps = sharded.distribute(state)
    seen = []

    def always_overflowing(s, caps):
        seen.append(caps)
        return lambda shard, step0, n: (shard, np.zeros(1, np.int32), np.array([[0, 0, caps.halo + 1, 0]]),
                                        np.zeros(1, np.int32))

    monkeypatch.setattr(driver, "_chunk", always_overflowing)
    with pytest.raises(HaloOverflow, match=r"buffers \['halo'\] still overflow after 2 re-allocations"):
        sharded.advance(shard, caps, 0, 5, max_reallocations=2)
    assert [c.halo for c in seen] == sorted({c.halo for c in seen}) and len(seen) == 3   # grown each time
    assert len(sharded.collect(shard).r) == solver.scene.n


def test_capacities_are_validated_and_grow_to_what_was_needed():
    from sph import ConfigError
    from sph.parallel import Capacities
    from sph.parallel.driver import grown

    caps = Capacities(owned=10, halo=4, migrate=2, cells=3, slots=8)
    with pytest.raises(ConfigError, match="capacities.halo"):
        Capacities(owned=10, halo=0, migrate=2, cells=3, slots=8)
    more = grown(caps, np.array([2, 30, 4, 1]))          # owned overflowed, the list overflowed
    assert more.owned >= 38 and more.halo == 4 and more.migrate == 2
    assert more.cells > caps.cells and more.slots > caps.slots


# ------------------------------------------------------------------------------------------------
# in a child process with 4 host devices
# ------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def results():
    flags = os.environ.get("XLA_FLAGS", "") + " --xla_force_host_platform_device_count=4"
    env = {**os.environ, "XLA_FLAGS": flags.strip()}
    proc = subprocess.run([sys.executable, __file__, *MATRIX], capture_output=True, text=True, env=env, timeout=900)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("key", [k for k in MATRIX if not k.startswith("grad")])
def test_sharded_rollout_equals_one_device(results, key):
    r = results[key]
    assert r["error"] < TOL, f"{key}: {r['worst']} differs by {r['error']:.3g} (relative) after {r['steps']} steps"
    assert r["particles"] == r["n"]
    if "refused" in r:
        assert "moved more than one slab" in r["refused"], r["refused"]


@pytest.mark.parametrize("key", [k for k in MATRIX if k.startswith("grad")])
def test_gradient_through_sharded_rollout_equals_one_device(results, key):
    r = results[key]
    assert r["valid"], r
    assert r["norm"] > 0 and r["error"] <= 1e-10, r


def test_two_processes_on_localhost_equal_one_device():
    """2 processes x 1 CPU device, `jax.distributed.initialize` on localhost, gloo collectives."""
    import socket

    with socket.socket() as s:
        s.bind(("localhost", 0))
        port = s.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if k != "XLA_FLAGS"}
    procs = [subprocess.Popen([sys.executable, __file__, "--process", str(i), str(port), TWO_PROCESSES],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env) for i in range(2)]
    try:
        outs = [p.communicate(timeout=300) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-4000:]
    r = json.loads(outs[0][0].strip().splitlines()[-1])[TWO_PROCESSES]
    assert r["error"] < TOL and r["particles"] == r["n"], r
    assert "moved more than one slab" in r["refused"], r


# ------------------------------------------------------------------------------------------------
# the children
# ------------------------------------------------------------------------------------------------

def _case(name):
    import sph
    from sph.cases import channel, ldc, tank, tgv, tgv3d

    if name == "tgv2d":
        return sph.build_solver(tgv.scene(0.05, tgv.material(100), tgv.METHODS["tvf"]), tgv.NUMERICS), None
    if name == "ldc":
        return sph.build_solver(*ldc.setup(0.05, 100, "tvf")), None
    if name == "dambreak":
        mat = sph.Material(rho_ref=1.0, eta=tank.DAM_BREAK_ETA, u_ref=tank.u_ref(1.0, 0.5))
        sc = tank.scene(0.05, mat, tank.DAM_BREAK_EFFECTS, width=0.5, height=0.5, tank_length=2.0, tank_height=1.0)
        solver = sph.build_solver(sc, tank.DAM_BREAK_NUMERICS)
        return solver, lambda st: tank.hydrostatic(st, solver.eos, 1.0, 1.0, tank.surface(0.05, 0.5))
    if name == "channel":
        mat = sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0, kappa=7.313, c_p=305.27)
        sc = channel.scene(0.05, mat, sph.Effects(walls="no_slip", heat=True, gravity=(2.3, 0.0)), length=1.0,
                           height=0.2, noise_factor=0.05)
        return sph.build_solver(sc, sph.Numerics(p_bg_factor=0.05)), None
    if name == "tgv3d":
        return sph.build_solver(tgv3d.scene(tgv3d.dx_for(16), tgv3d.material(100), tgv3d.METHODS["tvf"]),
                                sph.Numerics()), None
    raise ValueError(name)


def _start(name):
    solver, start = _case(name)
    state, nbrs = solver.init_fn()
    if start is not None:
        state = start(state)
        nbrs = solver.neighbors.allocate(state.r)
    return solver, state, nbrs


def _equality(name, devices, cache, reference=True, steps=None):
    import jax

    from sph.parallel import build_sharded
    from sph.rollout import advance, make_chunk

    steps = steps or (10 if name == "tgv3d" else STEPS)
    if name not in cache:
        solver, state0, nbrs = _start(name)
        ref = (advance(jax.jit(make_chunk(solver.step_fn, steps)), solver.neighbors, state0, nbrs, 0, steps)[0]
               if reference else None)
        cache[name] = solver, state0, ref
    solver, state0, ref = cache[name]
    sharded = build_sharded(solver, devices, chunk_length=steps)
    shard, caps = sharded.distribute(state0, sharded.capacities(state0, list_margin=1.6))   # lattice starts
    shard, caps, reallocs = sharded.advance(shard, caps, 0, steps)
    got = sharded.collect(shard)     # refuses a particle missing or held twice
    out = {"reallocations": reallocs, "n": solver.scene.n, "particles": int(len(got.r)), "steps": steps}
    if devices > 1:   # a particle crossing more than one slab in a step is refused (same program, no compile)
        from sph.parallel import SlabSkipped

        i = int(np.flatnonzero(np.asarray(got.tag) == 0)[0])
        u = np.array(got.u)
        u[i, sharded.decomp.axis] = 2.5 * sharded.decomp.width / solver.dt
        fast = got.replace(u=u, v=u)
        try:
            sharded.advance(sharded.distribute(fast, caps)[0], caps, steps, 1)
            out["refused"] = ""
        except SlabSkipped as e:
            out["refused"] = str(e)
    if ref is None:
        return out
    err = {}
    for k in ("r", "u", "v", "rho", "p", "dudt", "dvdt", "T"):
        a, b = getattr(got, k), getattr(ref, k)
        if b is not None:
            b = np.asarray(b)
            err[k] = float(np.max(np.abs(np.asarray(a) - b))) / max(1.0, float(np.max(np.abs(b))))
    worst = max(err, key=err.get)
    return {**out, "error": err[worst], "worst": worst}


def _gradient(devices, steps=10):
    """Fig. 1's derivative through the sharded rollout: d E_kin(after `steps` steps) / d r0 of every
    particle of a TGV (gradcheck), by reverse mode through `ShardedSolver.rollout` with respect to the
    devices' position rows, mapped back by particle id, against the single-device scan rollout's."""
    from dataclasses import replace

    import jax
    import jax.numpy as jnp

    from sph.diagnostics import kinetic_energy
    from sph.parallel import build_sharded
    from sph.parallel.driver import gather, overflows
    from sph.rollout import scan_rollout

    solver, state0, nbrs = _start("tgv2d")

    def single(r):
        out, _, bad = scan_rollout(solver.step_fn, state0.replace(r=r), nbrs, steps, guard=None)
        return kinetic_energy(out), bad

    g1, bad = jax.jit(jax.grad(single, has_aux=True))(state0.r)
    sharded = build_sharded(solver, devices)
    shard, caps = sharded.distribute(state0)
    roll = sharded.rollout(caps, steps)

    def multi(r):
        out, needs, far = roll(replace(shard, state=shard.state.replace(r=r)), 0)
        st = out.state.replace(tag=jnp.where(out.valid, out.state.tag, -1))   # padding rows are no fluid
        return kinetic_energy(st), (needs, far)

    g2, (needs, far) = jax.jit(jax.grad(multi, has_aux=True))(shard.state.r)
    g2, valid, pid = (np.asarray(gather(x)) for x in (g2, shard.valid, shard.pid))
    g1 = np.asarray(g1)
    mapped = np.full_like(g1, np.nan)
    mapped[pid[valid]] = g2[valid]
    needs = np.asarray(gather(needs)).reshape(-1, 4)[0]
    ok = not bool(bad) and not np.asarray(overflows(needs, caps)).any() and int(np.asarray(far)[0]) == 0
    return {"error": float(np.max(np.abs(mapped - g1)) / np.max(np.abs(g1))), "norm": float(np.linalg.norm(g1)),
            "valid": ok and bool(np.all(np.isfinite(mapped)))}


def main(keys):
    import time

    import jax

    import sph

    sph.set_cpu_defaults()
    sph.precision.enable_x64()
    assert len(jax.devices()) >= 4, jax.devices()
    out, cache = {}, {}
    for key in keys:
        name, devices = key.split(":")
        t = time.time()
        out[key] = _gradient(int(devices)) if name == "grad" else _equality(name, int(devices), cache)
        out[key]["seconds"] = round(time.time() - t, 2)
        print(key, out[key], file=sys.stderr, flush=True)
    print(json.dumps(out))


def main_process(process: int, port: int, keys):
    """One of 2 processes x 1 CPU device on localhost (gloo collectives): the same checks over the
    devices of both processes; process 0 prints the JSON line."""
    import jax

    jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(coordinator_address=f"localhost:{port}", num_processes=2, process_id=process,
                               local_device_ids=[0])
    import sph

    sph.precision.enable_x64()
    assert jax.process_count() == 2 and len(jax.devices()) == 2, jax.devices()
    out, cache = {}, {}
    for key in keys:
        name, devices, steps = key.split(":")
        out[key] = _equality(name, int(devices), cache, reference=process == 0, steps=int(steps))
    if process == 0:
        print(json.dumps(out))
    jax.distributed.shutdown()


if __name__ == "__main__":
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    if sys.argv[1] == "--process":
        main_process(int(sys.argv[2]), int(sys.argv[3]), sys.argv[4:])
    else:
        main(sys.argv[1:])
