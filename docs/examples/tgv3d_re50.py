"""3D Taylor-Green vortex at Re = 50, validated recipe, against JAX-Fluids. Args: [n_side t_end relax_steps]."""
import dataclasses
import sys

import sph
from sph import simulate
from sph.cases import tgv3d, tgv3d_reference

sph.set_cpu_defaults()  # XLA's fast CPU path for the pair sums: call before any JAX computation

n, t_end, steps = ([float(a) for a in sys.argv[1:]] + [16, 2.0, 1000][len(sys.argv) - 1:])[:3]
scene, numerics = tgv3d.setup(tgv3d.dx_for(int(n)), re=50, progress=False,
                              relaxation=dataclasses.replace(tgv3d.RELAXATION, steps=int(steps)))
solver = sph.build_solver(scene, numerics)
res = simulate.run(solver, *solver.init_fn(), t_end, max(1, solver.n_steps(t_end) // 40), progress=False)
e = tgv3d.e_kin_normalised(res.e_kin, scene.material.rho_ref)
out = tgv3d_reference.compare(res.t, e, tgv3d_reference.reference(re=50))
print(f"E_kin(0) = {e[0]:.5f} (exact 0.125), E_kin({res.t[-1]:.2f}) = {e[-1]:.5f}, "
      f"RMS deviation from JAX-Fluids {out['e_kin_rms_rel']:.2%}")
print(f"decay rate over [0, {out['early_window']:.2f}]: {out['early_rate']:.5f} (JAX-Fluids {out['ref_early_rate']:.5f})")
