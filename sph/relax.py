"""Particle relaxation (JAX-SPH's 'rlx' mode): even, non-lattice initial positions for any scene.

A jittered lattice at rest is advanced with the transport-velocity formulation (Adami 2013) and an
EoS background pressure p_bg_factor * p_ref until the particles spread evenly; optionally the velocity
is zeroed every `quench_every` steps (a damped relaxation that settles instead of sloshing). Only
the fluid moves; walls, if the scene has them, keep their places. The relaxation is geometric: the
scene's gravity and body force are off (as in JAX-SPH's relaxation mode, which zeroes the external
acceleration), so no flow is driven while the particles spread; its viscosity is the scene's unless
`Relaxation.eta` says otherwise (a very viscous scene would otherwise relax under its viscous time
step limit cfl h^2 rho_ref / eta, sph.timestep).

    r, info = relax(scene, numerics, Relaxation(steps=5000, quench_every=200))
"""
import dataclasses
import time
from dataclasses import dataclass
from typing import Optional

import jax
import jax.numpy as jnp
import numpy as np
from tqdm.auto import tqdm

from . import diagnostics, simulate
from .config import Numerics
from .errors import require
from .rollout import advance, make_chunk
from .scene import Scene
from .solver import build_solver


@dataclass(frozen=True)
class Relaxation:
    """Settings of a relaxation.

    steps         number of relaxation steps
    p_bg_factor   EoS background pressure / p_ref during relaxation
    noise_factor  standard deviation of the Gaussian lattice jitter / dx (used by the caller that
                  builds the jittered lattice)
    seed          seed of the jitter
    quench_every  set the velocity to zero every this many steps (0 = never, JAX-SPH's choice); the
                  quench removes the kinetic energy the relaxation keeps sloshing around, so the
                  particles settle instead of still moving at u_max ~ 0.025 after 5000 steps
    eta           dynamic viscosity during the relaxation; None = the scene's material.eta (JAX-SPH's
                  choice). At nu = 100 and dx 0.02 the viscous limit makes dt 1e-6 (cfl 0.25, h = dx): eta 0.01
                  relaxes at the convective dt instead
    """

    steps: int = 5000
    p_bg_factor: float = 0.02
    noise_factor: float = 0.25
    seed: int = 123
    quench_every: int = 0
    eta: Optional[float] = None

    def __post_init__(self):
        require(self.steps >= 0, "relaxation.steps", f"must be >= 0, got {self.steps}")
        require(bool(np.isfinite(self.p_bg_factor)) and self.p_bg_factor >= 0, "relaxation.p_bg_factor",
                f"must be finite and >= 0, got {self.p_bg_factor}")
        require(bool(np.isfinite(self.noise_factor)) and self.noise_factor >= 0, "relaxation.noise_factor",
                f"must be finite and >= 0, got {self.noise_factor}")
        require(self.quench_every >= 0, "relaxation.quench_every", f"must be >= 0, got {self.quench_every}")
        require(self.eta is None or (bool(np.isfinite(self.eta)) and self.eta >= 0), "relaxation.eta",
                f"must be finite and >= 0 (or null: the scene's), got {self.eta}")
        require(not self.quench_every or self.steps % self.quench_every == 0, "relaxation.quench_every",
                f"must divide relaxation.steps ({self.steps}), got {self.quench_every}")


def relax(scene: Scene, numerics: Numerics, rlx: Relaxation, progress: bool = True, desc: str = "relax"):
    """Relax the fluid particles of `scene` (its velocities are ignored: it starts at rest, with TVF,
    the relaxation's background pressure, no gravity or body force, and `rlx.eta` if given). Returns
    (positions (N, dim) float64, info dict)."""
    material = scene.material if rlx.eta is None else dataclasses.replace(scene.material, eta=rlx.eta)
    scene = dataclasses.replace(scene, u=np.where(scene.fluid_mask[:, None], 0.0, scene.u), material=material,
                                body_force=None,
                                effects=dataclasses.replace(scene.effects, tvf=True, riemann=False, gravity=None,
                                                            density_evolution=False, density_reinit_every=0))
    solver = build_solver(scene, dataclasses.replace(numerics, p_bg_factor=rlx.p_bg_factor))
    state, nbrs = solver.init_fn()
    rho_ref = scene.material.rho_ref
    rho_err0 = float(diagnostics.density_error(state, rho_ref))
    if rlx.steps == 0:
        return np.asarray(state.r, np.float64), {"steps": 0}
    info = {"steps": rlx.steps, "dt": solver.dt, "n_particles": scene.n, "density_error_start": rho_err0}
    if not rlx.quench_every:
        res = simulate.run(solver, state, nbrs, t_end=rlx.steps * solver.dt, write_every=max(1, rlx.steps // 10),
                           n_steps=rlx.steps, progress=progress, desc=desc)
        info.update(wall_s=res.wall_s, compile_s=res.compile_s, density_error_end=float(res.density_error[-1]),
                    u_max_end=float(res.u_max[-1]))
        return np.asarray(res.state.r, np.float64), info
    q = rlx.quench_every
    chunk = jax.jit(make_chunk(solver.step_fn, q))
    t0 = time.perf_counter()
    u_max_end = 0.0
    for k in tqdm(range(rlx.steps // q), desc=f"{desc} (quench every {q})", disable=not progress):
        state, nbrs, _ = advance(chunk, solver.neighbors, state, nbrs, k * q, q)
        u_max_end = float(diagnostics.u_max(state))
        if not np.isfinite(u_max_end):
            raise RuntimeError(f"relaxation blew up within steps {k * q}-{(k + 1) * q}: u_max = {u_max_end}; "
                               f"dt = {solver.dt:.4g} (limits {solver.dt_limits}) — lower numerics.dt or cfl")
        state = state.replace(u=jnp.zeros_like(state.u))
    info.update(quench_every=q, wall_s=time.perf_counter() - t0,
                density_error_end=float(diagnostics.density_error(state, rho_ref)), u_max_end=u_max_end)
    return np.asarray(state.r, np.float64), info
