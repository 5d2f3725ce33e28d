"""Benchmark: peak memory and time of a gradient through a long rollout (a script, not a test).

L(r0) = E_kin after n steps of the 2D Taylor-Green vortex (TVF, Re = 100, lattice with 0.1 dx of
noise), differentiated with respect to the initial positions through `sph.rollout.rollout_objective`
(the objective `value_and_grad_rollout` differentiates), with three checkpointing schemes:
  none       plain reverse mode through `lax.scan` (stores every step's residuals)
  segments   `jax.checkpoint` over segments = round(sqrt(n)) segments
  nested     segments as above, and every step inside a segment checkpointed too (`remat_steps`)
Each configuration runs in a fresh subprocess, which reports

  est_GB   the compiled executable's memory_analysis(): temp + argument + output bytes
  rss_GB   the process' peak RSS during the run above its RSS just before it (the peak is reset
           through /proc/self/clear_refs after compilation; where that is refused, ru_maxrss after
           the run minus ru_maxrss after compilation, which can under-read if compilation peaked higher)
  compile_s, run_s   compilation, and one gradient evaluation (forward + backward)
  other_load   other work on the machine during run_s, in cores (lab.other_load; 0 idle)

Configurations whose estimate exceeds --limit-gb are compiled but not run. Table printed and written
to results/bench/grad_memory.csv (--quick: results/bench/grad_memory_quick.csv), which `make snapshot`
commits to docs/results/bench/ and `make restore` brings back.

    python bench/bench_grad_memory.py            # dx = 0.02 (2500 particles), 100 / 1000 / 5000 steps
    python bench/bench_grad_memory.py --quick    # dx = 0.05, 10 / 50 steps
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
GB = 1e9


def _rss_kb(field):
    for line in open("/proc/self/status"):
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


def measure_one(dx, n_steps, checkpoint, dtype, limit_gb):
    """One configuration, in this (fresh) process. Returns a dict of measurements."""
    import jax
    import jax.numpy as jnp

    import sph
    from sph.cases import tgv
    from sph.lattice import cartesian, jitter
    from sph.rollout import rollout_objective

    def kinetic_energy(state):
        return 0.5 * jnp.sum(state.mass[:, None] * state.u**2)

    r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), 0.1 * dx, seed=0, box=(1.0, 1.0))
    solver = sph.build_solver(tgv.scene(dx, sph.Material(eta=0.01), sph.Effects(tvf=True), r=r),
                              sph.Numerics(dtype=dtype))
    state0, nbrs = solver.init_fn()
    u0 = state0.u
    segments = int(round(n_steps ** 0.5)) if checkpoint != "none" else 0
    objective = rollout_objective(kinetic_energy, lambda r, nb: solver.state_at(r, u0, nb), solver.step_fn,
                                  solver.neighbors, n_steps, segments=segments, remat_steps=checkpoint == "nested")
    t0 = time.perf_counter()
    compiled = jax.jit(jax.value_and_grad(objective, has_aux=True)).lower(state0.r, nbrs).compile()
    compile_s = time.perf_counter() - t0
    ma = compiled.memory_analysis()
    est = (ma.temp_size_in_bytes + ma.argument_size_in_bytes + ma.output_size_in_bytes) / GB
    out = dict(dx=dx, n=state0.r.shape[0], dtype=dtype, steps=n_steps, segments=segments,
               K=nbrs.max_occupancy, est_GB=est, temp_GB=ma.temp_size_in_bytes / GB, compile_s=compile_s,
               rss_GB=float("nan"), run_s=float("nan"), status="ok")
    if est > limit_gb:
        out["status"] = f"not run (would need {est:.1f} GB)"
        return out
    jax.block_until_ready((state0.r, nbrs))
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")  # reset the peak RSS (VmHWM, and with it ru_maxrss) to the current RSS
        base_kb, how = _rss_kb("VmRSS"), "clear_refs"
    except OSError:
        base_kb, how = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, "ru_maxrss"
    from lab.other_load import OtherLoad

    t0 = time.perf_counter()
    with OtherLoad() as load:  # other work on the machine while the gradient was timed, in cores
        (loss, (_, invalid)), grad = compiled(state0.r, nbrs)
        jax.block_until_ready(grad)
    out["run_s"] = time.perf_counter() - t0
    out["other_load"] = load.fields()["other_load"]
    peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    out["rss_GB"] = max(peak_kb - base_kb, 0) * 1024 / GB
    out["rss_method"] = how
    import numpy as np
    g = np.asarray(grad)
    out["loss"] = float(loss)
    out["grad_norm"] = float(np.linalg.norm(g))
    if bool(invalid):
        out["status"] = "neighbour list overflowed: result invalid"
    elif not np.all(np.isfinite(g)):
        out["status"] = "non-finite gradient"
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="dx = 0.05, 10 and 50 steps, float64")
    ap.add_argument("--dtypes", default="float64", help="comma-separated, e.g. float64,float32")
    ap.add_argument("--limit-gb", type=float, default=8.0, help="do not run configurations estimated above this")
    ap.add_argument("--one", help=argparse.SUPPRESS)  # internal: JSON config of a single measurement
    args = ap.parse_args()
    if args.one:
        print("RESULT " + json.dumps(measure_one(**json.loads(args.one))), flush=True)
        return
    from sph.xla_cpu import set_cpu_defaults

    set_cpu_defaults()  # in XLA_FLAGS, which the measuring children inherit
    import pandas as pd

    if args.quick:
        dx, steps, dtypes = 0.05, [10, 50], ["float64"]
    else:
        dx, steps, dtypes = 0.02, [100, 1000, 5000], args.dtypes.split(",")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    rows = []
    for dtype in dtypes:
        for n in steps:
            for ckpt in ("none", "segments", "nested"):
                cfg = dict(dx=dx, n_steps=n, checkpoint=ckpt, dtype=dtype, limit_gb=args.limit_gb)
                proc = subprocess.run([sys.executable, __file__, "--one", json.dumps(cfg)], env=env,
                                      capture_output=True, text=True)
                lines = [l for l in proc.stdout.splitlines() if l.startswith("RESULT ")]
                if proc.returncode or not lines:
                    row = dict(dx=dx, dtype=dtype, steps=n, status=f"failed (rc {proc.returncode}): "
                               + (proc.stderr.strip().splitlines() or ["?"])[-1][:120])
                else:
                    row = json.loads(lines[-1][len("RESULT "):])
                row["checkpoint"] = ckpt
                rows.append(row)
                print(f"{dtype} {n:5d} steps checkpoint={ckpt:8s}: est {row.get('est_GB', float('nan')):.3f} GB, "
                      f"rss {row.get('rss_GB', float('nan')):.3f} GB, run {row.get('run_s', float('nan')):.1f} s, "
                      f"{row['status']}", flush=True)
    cols = ["dtype", "dx", "n", "K", "steps", "checkpoint", "segments", "est_GB", "temp_GB", "rss_GB",
            "compile_s", "run_s", "other_load", "grad_norm", "status", "date"]
    df = pd.DataFrame(rows)
    df["date"] = time.strftime("%Y-%m-%d", time.gmtime())
    df = df[[c for c in cols if c in df.columns]]
    import jax
    print(f"\ngradient of E_kin(n steps) w.r.t. r0, TGV 2D TVF, jax {jax.__version__} on "
          f"{jax.devices()[0].platform}; est = memory_analysis temp+arg+out, rss = peak RSS above pre-run")
    with pd.option_context("display.width", 200, "display.max_columns", 20, "display.float_format", "{:.3g}".format):
        print(df.to_string(index=False))
    out = ROOT / "results" / "bench" / ("grad_memory_quick.csv" if args.quick else "grad_memory.csv")
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(out, index=False)
    print(f"written {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
