"""The RPF 2D dataset's settings (`data` of experiments/sitl/config.yaml), alone in this module because the
dataset's key reads it: `sitl.settings.data_fingerprint` hashes this file and sitl/generate.py (and
the sph modules they import), so an edit to the model, training, evaluation or study settings in
sitl/settings.py does not make the dataset again.
"""
from dataclasses import dataclass, field
from typing import Optional

import sph
from lab.configtools import require
from sph.relax import Relaxation


@dataclass(frozen=True)
class Data:
    """The RPF 2D dataset (LagrangeBench layout).

    dx, nu, g          spacing, kinematic viscosity, body-force magnitude (box 1 x 2)
    c_ref_factor       c_ref = c_ref_factor * u_ref (u_ref = 1)
    p_bg_factor        Tait background pressure / p_ref of the data run (and of SitL's solver)
    dt                 SPH time step of the data run (null: the CFL limit)
    write_every        SPH steps per stored frame: frame interval = dt * write_every
    t_discard          simulated time before the first stored frame (start-up transient)
    frames             stored frames per split: train, valid, test (cut from one trajectory per seed,
                       in this order, LagrangeBench's 2:1:1)
    seeds              independent trajectories (relaxation seeds seed0 .. seed0 + seeds - 1), run as
                       one vmapped program sharded across devices; group k of each split = seed k
    relaxation         TVF relaxation at rest (sph.Relaxation; its seed is seed0)
    dtype              precision of the data run (stored positions are float32)
    connectivity_radius_factor   default_connectivity_radius / dx (LagrangeBench: 1.45)
    profile_tol        validation: max |u_data - u_exact| / u_max over the first window of train
    profile_window     frames in that window
    capacity_multiplier  neighbour slots of the data run relative to the current maximum
    """

    dx: float
    dt: Optional[float] = None
    write_every: int = 20
    t_discard: float = 0.0
    frames: tuple[int, ...] = (200, 100, 100)
    seeds: int = 1
    nu: float = 0.1
    g: float = 1.0
    c_ref_factor: float = 10.0
    p_bg_factor: float = 0.05
    relaxation: Relaxation = field(default_factory=lambda: Relaxation(steps=1000, p_bg_factor=0.02,
                                                                      noise_factor=0.1, seed=0,
                                                                      quench_every=100))
    dtype: str = "float64"
    connectivity_radius_factor: float = 1.45
    profile_tol: float = 0.05
    profile_window: int = 10
    capacity_multiplier: float = 1.25

    def __post_init__(self):
        for key, side in (("dx", 1.0), ("dx", 2.0)):
            n = side / self.dx
            require(self.dx > 0 and abs(n - round(n)) < 1e-6, f"data.{key}",
                    f"must divide the 1 x 2 box into whole cells, got {self.dx}")
        require(self.dt is None or self.dt > 0, "data.dt", f"must be positive or null, got {self.dt}")
        require(self.write_every >= 1, "data.write_every", f"must be >= 1, got {self.write_every}")
        require(self.t_discard >= 0, "data.t_discard", f"must be >= 0, got {self.t_discard}")
        require(len(self.frames) == 3, "data.frames", f"needs 3 entries (train, valid, test), got {self.frames}")
        for i, n in enumerate(self.frames):
            require(n >= 3, f"data.frames[{i}]", f"needs at least 3 frames, got {n}")
        require(self.seeds >= 1, "data.seeds", f"must be >= 1, got {self.seeds}")
        require(self.nu > 0, "data.nu", f"must be positive, got {self.nu}")
        require(self.dtype in ("float32", "float64"), "data.dtype", f"{self.dtype!r} is not float32 or float64")
        require(self.profile_tol > 0, "data.profile_tol", f"must be positive, got {self.profile_tol}")
        require(2 <= self.profile_window <= self.frames[0], "data.profile_window",
                f"must be in [2, frames[0] = {self.frames[0]}], got {self.profile_window}")
        require(self.connectivity_radius_factor > 0, "data.connectivity_radius_factor", "must be positive")

    @property
    def material(self) -> sph.Material:
        return sph.Material(rho_ref=1.0, eta=self.nu, u_ref=1.0)

    def numerics(self, dt=None, dtype=None, p_bg_factor=None) -> sph.Numerics:
        """Standard SPH of the data run (quintic kernel, h = dx, summation density, Tait gamma 1)."""
        return sph.Numerics(kernel="quintic", h_factor=1.0, c_ref_factor=self.c_ref_factor, gamma=1.0,
                            p_bg_factor=self.p_bg_factor if p_bg_factor is None else p_bg_factor,
                            dt=self.dt if dt is None else dt, dtype=dtype or self.dtype,
                            capacity_multiplier=self.capacity_multiplier)

    @property
    def n_particles(self) -> int:
        return int(round(1.0 / self.dx)) * int(round(2.0 / self.dx))
