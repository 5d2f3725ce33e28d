"""Water at rest in a tank under gravity (validated recipe, hydrostatic start): spurious speeds. Args: [method dx]."""
import sys

import numpy as np

import sph
from sph import simulate
from sph.cases import tank

sph.set_cpu_defaults()  # XLA's fast CPU path for the pair sums: call before any JAX computation

method, dx = (sys.argv[1:] + ["sph", "0.05"][len(sys.argv) - 1:])[:2]
H = 0.5
scene, numerics, start = tank.at_rest(float(dx), width=1.0, height=H, method=method)
solver = sph.build_solver(scene, numerics)
t_end = 10 * np.sqrt(H)  # ten free-fall times sqrt(H / g), g = 1
res = simulate.run(solver, *start(solver), t_end, solver.n_steps(t_end) // 20, progress=False)
print(f"{method}: max |u| / sqrt(gH) at t = {res.t[-1]:.2f}: {res.u_max[-1] / np.sqrt(H):.2e} "
      f"(sph settles to ~6e-5; riemann does not: sph.cases.tank.AT_REST_EFFECTS)")
