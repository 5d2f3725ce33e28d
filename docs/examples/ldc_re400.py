"""Lid-driven cavity at Re = 400, validated recipe, against Ghia et al. (1982). Args: [dx t_end]."""
import sys

import sph
from sph import simulate
from sph.cases import ldc, ldc_reference

sph.set_cpu_defaults()  # XLA's fast CPU path for the pair sums: call before any JAX computation

dx, t_end = ([float(a) for a in sys.argv[1:]] + [0.02, 20.0][len(sys.argv) - 1:])[:2]
scene, numerics = ldc.setup(dx, re=400, method="tvf")
solver = sph.build_solver(scene, numerics)
last = []  # the states of the last tenth of the run, whose profiles are averaged
simulate.run(solver, *solver.init_fn(), t_end, max(1, solver.n_steps(t_end) // 50), progress=False,
             callback=lambda step, t, state: last.append(state) if t >= 0.9 * t_end else None)
out = ldc_reference.compare(solver, last, re=400)
print(f"t = {t_end:g}: RMS deviation from Ghia (Re 400): u {out['u_rms']:.4f}, v {out['v_rms']:.4f}")
print("u(0.5, y):", " ".join(f"{y:.3f}:{u:+.3f}" for y, u in zip(out["y"], out["u"])))
