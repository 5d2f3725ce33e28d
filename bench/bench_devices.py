"""Benchmark of the sharded step (sph.parallel, issue 40): scaling over devices, memory per device,
halo particles and exchange bytes per step (`make bench-devices`).

On a machine without accelerators the host is split into D XLA devices
(`--xla_force_host_platform_device_count`, set here before jax is imported): these are FORCED HOST
DEVICES, which share this machine's cores (2 here), so the speed-up over one device is bounded by
the core count and every D > 1 pays the exchange with no extra hardware. On GPUs the same script runs
unchanged over the visible devices and its weak-scaling efficiency is the number that matters.

  strong   TGV 2D (TVF, periodic), n^2 particles on D = 1, 2, 4 devices: time per step
  weak     the same with D unit squares side by side (box D x 1): n^2 particles per device
  per run  the single-device solver's time per step (baseline), the sharded time per step, speed-up
           or weak efficiency (t_1 / t_D), memory per device (XLA's plan of the compiled chunk:
           arguments + outputs + temporaries, per device), halo particles per device against the
           surface-to-volume estimate (2 faces x halo width / slab width x particles per device),
           and the bytes exchanged per step: payload (the particles actually sent, times the bytes
           of the fields of the exchange plan) and wire (the fixed-capacity buffers ppermute moves).

    python bench/bench_devices.py                 # n = 64, D = 1 2 4
    python bench/bench_devices.py --n 128 --devices 1 2 4 8 --steps 50
"""
import argparse
import os
import sys
import time

_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _force_devices(d: int):
    flag = "--xla_force_host_platform_device_count"
    flags = os.environ.get("XLA_FLAGS", "")
    if flag not in flags:
        os.environ["XLA_FLAGS"] = f"{flags} {flag}={d}".strip()


def tgv_strip(n: int, width: int):
    """TGV 2D, TVF, in the periodic box (width x 1), n^2 particles per unit square (lattice + noise)."""
    import numpy as np

    import sph
    from sph.domain import Domain
    from sph.lattice import cartesian, jitter
    from sph.state import FLUID

    dx = 1.0 / n
    box = (float(width), 1.0)
    r = jitter(cartesian([0.0, 0.0], list(box), dx), 0.05 * dx, seed=0, box=box)
    x, y = r[:, 0], r[:, 1]
    u = np.stack([-np.cos(2 * np.pi * x) * np.sin(2 * np.pi * y), np.sin(2 * np.pi * x) * np.cos(2 * np.pi * y)], 1)
    return sph.Scene(name="tgv_strip", dx=dx, domain=Domain(box=box, periodic=(True, True)),
                     material=sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0), effects=sph.Effects(tvf=True), r=r, u=u,
                     tag=np.full(len(r), FLUID, np.int32))


def field_bytes(state, names, dim) -> int:
    """Bytes per particle of the fields `names` (vectors dim components; tag, phase int32)."""
    vec = {"r", "u", "v", "dudt", "dvdt", "u_visc", "v_stress", "normal"}
    item = state.r.dtype.itemsize
    return sum((dim if n in vec else 1) * (4 if n in ("tag", "phase") else item) for n in names)


def timed(fn, *args, repeats=5):
    import jax

    best = float("inf")
    for _ in range(repeats):
        t = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - t)
    return best


def measure(scene, devices, steps):
    import jax
    import numpy as np

    import sph
    from sph.parallel import build_sharded
    from sph.parallel.layout import halo_counts
    from sph.rollout import make_chunk

    solver = sph.build_solver(scene, sph.Numerics())
    state, nbrs = solver.init_fn()
    chunk1 = jax.jit(make_chunk(solver.step_fn, steps))
    jax.block_until_ready(chunk1(state, nbrs, 0, steps))
    t1 = timed(chunk1, state, nbrs, 0, steps) / steps
    sharded = build_sharded(solver, devices, chunk_length=steps)
    shard, caps = sharded.distribute(state)
    fn = sharded.chunk(caps)
    compiled = fn.lower(shard, 0, steps).compile()
    out = compiled(shard, 0, steps)
    jax.block_until_ready(out)
    if int(np.asarray(out[1])[0]) != steps:
        shard, caps, _ = sharded.advance(shard, caps, 0, steps)
        fn = sharded.chunk(caps)
        compiled = fn.lower(shard, 0, steps).compile()
    td = timed(compiled, shard, 0, steps) / steps
    mem = compiled.memory_analysis()
    per_dev = (mem.argument_size_in_bytes + mem.output_size_in_bytes + mem.temp_size_in_bytes) if mem else float("nan")
    final = sharded.collect(compiled(shard, 0, steps)[0])
    halos = halo_counts(sharded.decomp, final.r)
    halo_dev = float(halos.sum(1).mean())
    estimate = sharded.decomp.halo_estimate(scene.n, scene.domain.box)
    plan = sharded.plan
    per_particle = field_bytes(final, plan.fields_per_step(), scene.dim) + 1          # + the halo's valid flag
    mig_row = field_bytes(final, [n for n in vars(final) if getattr(final, n) is not None], scene.dim) + 4 + 1 + 8 + 4
    payload = halos.sum() * per_particle if devices > 1 else 0
    wire = devices * 2 * (caps.halo * per_particle + caps.migrate * mig_row) if devices > 1 else 0
    return dict(n=scene.n, D=devices, t1_ms=1e3 * t1, tD_ms=1e3 * td, mem_MB=per_dev / 2**20, halo=halo_dev,
                halo_est=estimate, payload_kB=payload / 1024, wire_kB=wire / 1024, caps=caps)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=64, help="particles per side of a unit square")
    p.add_argument("--devices", type=int, nargs="+", default=[1, 2, 4])
    p.add_argument("--steps", type=int, default=50)
    a = p.parse_args(argv)
    _force_devices(max(a.devices))
    sys.path.insert(0, _ROOT)
    import jax

    import sph

    sph.set_cpu_defaults()
    sph.precision.enable_x64()
    kind = jax.devices()[0].platform
    label = (f"FORCED HOST DEVICES on {os.cpu_count()} CPU cores (they share the cores: speed-up <= {os.cpu_count()})"
             if kind == "cpu" else f"{len(jax.devices())} x {jax.devices()[0].device_kind}")
    print(f"bench-devices: TGV 2D TVF float64, {a.steps} steps per timing; {label}")
    head = (f"{'run':<7}{'D':>3}{'N':>8}{'1 dev ms':>10}{'D dev ms':>10}{'speed-up':>10}{'eff':>7}{'MB/dev':>9}"
            f"{'halo/dev':>10}{'S/V est':>9}{'payload kB':>12}{'wire kB':>10}")
    for run in ("strong", "weak"):
        print(head)
        base = None
        for d in a.devices:
            r = measure(tgv_strip(a.n, d if run == "weak" else 1), d, a.steps)
            base = base or r["tD_ms"]
            speed = r["t1_ms"] / r["tD_ms"] if run == "strong" else float("nan")
            eff = base / r["tD_ms"] if run == "weak" else speed / d
            print(f"{run:<7}{d:>3}{r['n']:>8}{r['t1_ms']:>10.2f}{r['tD_ms']:>10.2f}{speed:>10.2f}{eff:>7.2f}"
                  f"{r['mem_MB']:>9.1f}{r['halo']:>10.0f}{r['halo_est']:>9.0f}{r['payload_kB']:>12.1f}"
                  f"{r['wire_kB']:>10.1f}",
                  flush=True)
    print("speed-up: single-device solver's time / sharded time (strong); eff: speed-up / D (strong), "
          "t(D=first) / t(D) at fixed particles per device (weak). payload: halo particles x exchanged field bytes per "
          "step; wire: the fixed halo and migration buffers ppermute moves per step.")


if __name__ == "__main__":
    main()
