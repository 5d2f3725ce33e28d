"""Plane Couette flow started from rest (top wall moving at U), against the exact series. Args: [dx t_end]."""
import sys

import numpy as np

import sph
from sph import simulate
from sph.cases import channel

sph.set_cpu_defaults()  # XLA's fast CPU path for the pair sums: call before any JAX computation

dx, t_end = ([float(a) for a in sys.argv[1:]] + [0.02, 1.0][len(sys.argv) - 1:])[:2]
U, H, mat = 1.0, 0.2, sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0)
scene = channel.scene(dx, mat, sph.Effects(tvf=True, walls="no_slip"), length=0.4, height=H, wall_velocity=U)
solver = sph.build_solver(scene)
res = simulate.run(solver, *solver.init_fn(), t_end, 100, progress=False)
fluid = scene.fluid_mask; y, u = np.asarray(res.state.r)[fluid, 1] - channel.offset(dx), np.asarray(res.state.u)[fluid, 0]
exact = channel.couette_profile(y, res.t[-1], U, H, mat.eta / mat.rho_ref)
print(f"t = {res.t[-1]:.3f}: RMS |u - u_exact| / U = {np.sqrt(np.mean((u - exact) ** 2)) / U:.4f}, "
      f"max {np.abs(u - exact).max() / U:.4f} ({fluid.sum()} fluid particles)")
