"""The thermal studies (JAX-SPH, Toshev et al. 2024; the protocol is lab.experiment's): two kinds of
run in one folder, each with its own table in results/<profile>/thermal/.

sine_dx<dx>     the heat operator against the analytical decay of T = T0 + A sin(k x) in the periodic
                unit square at rest (one run per diffusion.dx) -> sine_metrics.csv (the heat
                validation): decay_rate_relerr (least-squares slope of log A(t) against the exact
                alpha k^2), amplitude_relerr_tend and _max, the motion of a fluid that should stay at rest
channel_dx<dx>  JAX-SPH's hot channel (Fig. 10) -> channel_metrics.csv: the per-frame diagnostics of
                `ChannelProbe` (`channel_series`) summarized; the discrete maximum principle is
                checked (every temperature within [T_ref, T_hot] up to max_principle_tol): a
                violation fails the run step after the run is written

Both start from the solver's initial state built under jit (`initial_state`); the frames keep the
momentum velocity, density and temperature (KEEP).
"""
import math
from dataclasses import dataclass, field
from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

import sph
from sph import heat
from sph.cases import channel
from sph.domain import Domain
from sph.errors import require, require_finite
from sph.lattice import cartesian
from sph.scene import Scene
from sph.state import FLUID
from lab.layout import dx_tag
from lab.protocol import Table

TABLE = Table(rows="metrics", sort=("dx",), ascending=(False,), file=lambda run: f"{run.kind}_metrics.csv")
KEEP = ("momentum_velocity", "density", "temperature")

THERMAL_MATERIAL = sph.Material(rho_ref=1.0, eta=0.01, u_ref=1.0, kappa=7.313, c_p=305.27)


def _whole_cells(length: float, dx: float) -> bool:
    if not dx > 0:
        return False
    n = length / dx
    return round(n) >= 1 and abs(n - round(n)) < 1e-6


def _needs_heat_material(mat: sph.Material, where: str):
    require(mat.kappa is not None, f"{where}.material.kappa", "the heat equation needs a thermal conductivity")
    require(mat.c_p is not None, f"{where}.material.c_p", "the heat equation needs a specific heat capacity")


@dataclass(frozen=True)
class Diffusion:
    """T = T0 + amplitude sin(2 pi mode x / 1) in the periodic unit square, fluid at rest on a
    uniform lattice; exact decay of the amplitude exp(-alpha k^2 t), alpha = kappa / (rho_ref c_p),
    k = 2 pi mode. The full solver step runs (heat + momentum, particles free to move).

    dx             spacings of the convergence study
    report_dx      the spacing whose error is the headline number (and checked against target_relerr)
    frames         amplitude samples after t = 0
    target_relerr  |A_sim / A_exact - 1| at t_end that the report_dx run must meet
    """

    dx: tuple[float, ...]
    t_end: float
    report_dx: float
    material: sph.Material = THERMAL_MATERIAL
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    T0: float = 1.0
    amplitude: float = 0.1
    mode: int = 1
    frames: int = 20
    target_relerr: float = 0.01

    def __post_init__(self):
        require_finite(self, "diffusion")
        require(len(self.dx) > 0, "diffusion.dx", "needs at least one spacing")
        for i, dx in enumerate(self.dx):
            require(_whole_cells(1.0, dx), f"diffusion.dx[{i}]",
                    f"must divide the unit square into whole cells (1/dx integer), got {dx}")
            require(self.dx.index(dx) == i, f"diffusion.dx[{i}]", f"{dx} appears twice")
        require(any(abs(d - self.report_dx) < 1e-12 for d in self.dx), "diffusion.report_dx",
                f"{self.report_dx} is not one of diffusion.dx {list(self.dx)}")
        require(self.t_end > 0, "diffusion.t_end", f"must be positive, got {self.t_end}")
        require(self.amplitude != 0, "diffusion.amplitude", "must be non-zero")
        require(self.mode >= 1, "diffusion.mode", f"must be >= 1, got {self.mode}")
        require(self.frames >= 1, "diffusion.frames", f"must be >= 1, got {self.frames}")
        require(self.target_relerr > 0, "diffusion.target_relerr", f"must be positive, got {self.target_relerr}")
        _needs_heat_material(self.material, "diffusion")

    @property
    def alpha(self) -> float:
        return self.material.kappa / (self.material.rho_ref * self.material.c_p)

    @property
    def k(self) -> float:
        return 2.0 * math.pi * self.mode

    def amplitude_exact(self, t):
        return self.amplitude * np.exp(-self.alpha * self.k**2 * np.asarray(t))


@dataclass(frozen=True)
class Channel:
    """JAX-SPH's hot channel (cases/ht.py, ht.yaml); see config.yaml and sph/cases/channel.py."""

    dx: float
    t_end: float
    material: sph.Material = THERMAL_MATERIAL
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    effects: sph.Effects = field(default_factory=lambda: sph.Effects(walls="no_slip", heat=True,
                                                                     gravity=(2.3, 0.0)))
    length: float = 1.0
    height: float = 0.2
    wall_layers: int = 3
    noise_factor: float = 0.05
    seed: int = 123
    T_ref: float = 1.0
    T_hot: float = 1.23
    hot_half_width: float = 0.25
    zone_layers: int = 3
    frames: int = 60
    snapshot_times: tuple[float, ...] = (0.0, 0.3, 0.6, 0.9, 1.2, 1.5)
    max_principle_tol: float = 1e-9

    def __post_init__(self):
        require_finite(self, "channel")
        require(self.material.eta > 0, "channel.material.eta",
                "must be positive: the channel's laminar reference (Poiseuille start-up, u_bulk = g H^2 / (12 nu)) "
                f"needs a viscosity, got {self.material.eta}")
        fx = self.effects
        require(fx.heat, "channel.effects.heat", "the hot channel needs effects.heat: true")
        require(fx.walls is not None, "channel.effects.walls", "the channel needs walls (no_slip)")
        require(fx.gravity is not None and len(fx.gravity) == 2, "channel.effects.gravity",
                "the channel is driven by a 2D body force, e.g. [2.3, 0.0]")
        _needs_heat_material(self.material, "channel")
        require(_whole_cells(self.length, self.dx), "channel.dx",
                f"must divide channel.length = {self.length} into whole cells, got {self.dx}")
        require(_whole_cells(self.height, self.dx), "channel.dx",
                f"must divide channel.height = {self.height} into whole cells, got {self.dx}")
        require(self.wall_layers >= 1, "channel.wall_layers", f"must be >= 1, got {self.wall_layers}")
        require(self.zone_layers >= 0, "channel.zone_layers", f"must be >= 0, got {self.zone_layers}")
        require(self.T_hot > self.T_ref, "channel.T_hot", f"must exceed T_ref = {self.T_ref}, got {self.T_hot}")
        require(0 < self.hot_half_width <= self.length / 2, "channel.hot_half_width",
                f"must be in (0, length/2], got {self.hot_half_width}")
        require(self.t_end > 0, "channel.t_end", f"must be positive, got {self.t_end}")
        require(self.frames >= 1, "channel.frames", f"must be >= 1, got {self.frames}")
        require(len(self.snapshot_times) > 0, "channel.snapshot_times", "needs at least one time")
        for i, t in enumerate(self.snapshot_times):
            require(0 <= t <= self.t_end * (1 + 1e-9), f"channel.snapshot_times[{i}]",
                    f"{t} lies outside [0, t_end = {self.t_end}]")
        require(self.max_principle_tol >= 0, "channel.max_principle_tol", "must be >= 0")

    @property
    def alpha(self) -> float:
        return self.material.kappa / (self.material.rho_ref * self.material.c_p)

    @property
    def nu(self) -> float:
        return self.material.eta / self.material.rho_ref

    @property
    def g(self) -> float:
        return float(self.effects.gravity[0])


@dataclass(frozen=True)
class Settings:
    """One profile of config.yaml: the two studies' sections."""

    diffusion: Diffusion
    channel: Channel


# -- what a run builds ------------------------------------------------------------------------------
def sine_scene(d: Diffusion, dx: float) -> Scene:
    """Uniform lattice in the periodic unit square, at rest, T = T0 + A sin(k x)."""
    r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
    T = d.T0 + d.amplitude * np.sin(d.k * r[:, 0])
    return Scene(name="heat_sine", dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)),
                 material=d.material, effects=sph.Effects(heat=True), r=r, u=np.zeros_like(r),
                 tag=np.full(len(r), FLUID, np.int32), T=T)


def channel_scene(c: Channel) -> Scene:
    return channel.scene(c.dx, c.material, c.effects, length=c.length, height=c.height, layers=c.wall_layers,
                         noise_factor=c.noise_factor, seed=c.seed, T_ref=c.T_ref, T_hot=c.T_hot,
                         hot_half_width=c.hot_half_width, zone_layers=c.zone_layers)


# -- the runs -------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SineRun:
    """One spacing of the heat validation: everything its numbers depend on (the section but its
    spacing list and target; `diffusion`, read by its metrics only, stays out of its key)."""

    name: str
    dx: float
    material: sph.Material
    numerics: sph.Numerics
    T0: float
    amplitude: float
    mode: int
    t_end: float
    frames: int
    diffusion: Diffusion = field(metadata={"key": False})
    kind: ClassVar[str] = "sine"
    method: ClassVar[str] = "heat"
    case: ClassVar[str] = "heat_sine"


@dataclass(frozen=True)
class ChannelRun:
    """The hot channel of the profile (its whole section)."""

    name: str
    channel: Channel
    kind: ClassVar[str] = "channel"
    method: ClassVar[str] = "heat"
    case: ClassVar[str] = "hot_channel"

    @property
    def t_end(self) -> float:
        return self.channel.t_end

    @property
    def frames(self) -> int:
        return self.channel.frames


def runs(s: Settings) -> list:
    d, c = s.diffusion, s.channel
    return [SineRun(f"sine_{dx_tag(dx)}", dx, d.material, d.numerics, d.T0, d.amplitude, d.mode, d.t_end, d.frames, d)
            for dx in d.dx] + [ChannelRun(f"channel_{dx_tag(c.dx)}", c)]


def scene(run):
    if run.kind == "sine":
        return sine_scene(run.diffusion, run.dx), run.diffusion.numerics
    return channel_scene(run.channel), run.channel.numerics


def initial_state(run, solver: sph.Solver):
    """What `solver.init_fn()` returns, with the initial state built under jit (`solver.state_at`):
    the same numbers, but one compilation instead of several seconds of op-by-op dispatch."""
    r = jnp.asarray(solver.scene.r, solver.dtype)
    nbrs = solver.neighbors.allocate(r)
    return jax.jit(solver.state_at)(r, jnp.asarray(solver.scene.u, solver.dtype), nbrs), nbrs


def run_options(run) -> dict:
    if run.kind == "sine":
        return {"case": run.case}
    c = run.channel
    return {"case": run.case, "u_limit": c.numerics.c_ref_factor * c.material.u_ref}


# -- what a run measures ---------------------------------------------------------------------------
def metrics(run, traj: dict) -> dict:
    return sine_row(run, traj) if run.kind == "sine" else channel_row(run, traj)


def record(run, m: dict) -> dict:
    if run.kind == "sine":
        return {"target": "heat-validation", "errors": {"decay_rate": abs(m["decay_rate_relerr"]),
                                                        "amplitude_tend": abs(m["amplitude_relerr_tend"])}}
    return {"target": "fig10", "errors": {"u_bulk_end": abs(m["u_bulk_relerr_end"])}}


def sine_amplitude(r, T, d: Diffusion) -> float:
    """Projection of T - T0 on sin(k x): exact for the lattice mode (2/N sum_i (T_i - T0) sin(k x_i))."""
    r, T = np.asarray(r), np.asarray(T)
    return float(2.0 * np.mean((T - d.T0) * np.sin(d.k * r[:, 0])))


def sine_series(run: SineRun, traj: dict) -> pd.DataFrame:
    """t, amplitude, u_max, exact, relerr per frame."""
    d = run.diffusion
    s = pd.DataFrame({"time": traj["time"],
                      "amplitude": [sine_amplitude(r, T, d) for r, T in zip(traj["position"], traj["temperature"])],
                      "u_max": np.max(np.linalg.norm(traj["momentum_velocity"], axis=-1), axis=-1)})
    s["exact"] = d.amplitude_exact(s["time"])
    s["relerr"] = s["amplitude"] / s["exact"] - 1.0
    return s


def sine_row(run: SineRun, traj: dict) -> dict:
    d, dx, meta = run.diffusion, run.dx, traj["metadata"]
    s = sine_series(run, traj)
    t, a = s["time"].to_numpy(), s["amplitude"].to_numpy()
    disp = traj["position"][-1] - traj["position"][0]
    disp -= np.round(disp)  # minimum image in the unit box
    rate_exact = d.alpha * d.k**2
    rate_sim = -np.polyfit(t, np.log(a / d.amplitude), 1)[0]  # least-squares slope of log A(t)
    n_steps = int(traj["attrs"]["n_steps"])
    wall = float(traj["attrs"]["wall_s"])
    return {"case": "heat_sine", "dx": dx, "dtype": d.numerics.dtype, "n_particles": int(traj["particle_type"].shape[0]),
            "n_steps": n_steps, "dt": meta["dt"], "dt_thermal": meta["dt_limits"].get("thermal", np.nan),
            "t_end": float(t[-1]), "alpha": d.alpha, "k": d.k,
            "wall_s": wall, "compile_s": float(traj["attrs"]["compile_s"]),
            "ms_per_step": 1e3 * wall / n_steps if n_steps else np.nan,
            "amplitude_ratio_sim": float(a[-1] / d.amplitude),
            "amplitude_ratio_exact": float(d.amplitude_exact(t[-1]) / d.amplitude),
            "amplitude_relerr_tend": float(s["relerr"].iloc[-1]),
            "amplitude_relerr_max": float(np.max(np.abs(s["relerr"]))),
            "decay_rate_sim": float(rate_sim), "decay_rate_exact": float(rate_exact),
            "decay_rate_relerr": float(rate_sim / rate_exact - 1.0),
            "motion_allowed": True,  # the full step runs: particles are free to move, but at rest on a
            "u_max_max": float(s["u_max"].max()),  # uniform periodic lattice every force cancels
            "displacement_max": float(np.max(np.abs(disp))),
            "target_relerr": d.target_relerr,
            "meets_target": bool(max(abs(rate_sim / rate_exact - 1.0), abs(s["relerr"].iloc[-1])) <= d.target_relerr)}


def poiseuille_u(y, t, g: float, nu: float, height: float, terms: int = 200):
    """Start-up plane Poiseuille flow from rest between walls at y = 0 and y = height, body force g:
    u = g/(2 nu) y (H - y) - sum_{m odd} 4 g H^2/(nu pi^3 m^3) sin(m pi y/H) exp(-m^2 pi^2 nu t/H^2)."""
    y = np.asarray(y, float)[..., None]
    m = 2.0 * np.arange(terms) + 1.0
    series = (4 * g * height**2 / (nu * np.pi**3 * m**3)) * np.sin(m * np.pi * y / height) \
        * np.exp(-m**2 * np.pi**2 * nu * t / height**2)
    return g / (2 * nu) * y[..., 0] * (height - y[..., 0]) - series.sum(-1)


def poiseuille_bulk(t, g: float, nu: float, height: float, terms: int = 200) -> float:
    """Mean over the channel height of `poiseuille_u`: g H^2/(12 nu) - sum 8 g H^2/(nu pi^4 m^4) e^(...)."""
    m = 2.0 * np.arange(terms) + 1.0
    return float(g * height**2 / (12 * nu)
                 - np.sum(8 * g * height**2 / (nu * np.pi**4 * m**4) * np.exp(-m**2 * np.pi**2 * nu * t / height**2)))


class ChannelProbe:
    """Per-frame diagnostics of the hot channel.

    Q_hot   heat per unit time (and unit depth) that the heated wall segment gives the fluid:
            sum_{i fluid} m_i c_p (dT_i/dt restricted to neighbours j on the hot segment), evaluated
            with the solver's own conduction term `sph.heat.Conduction` (masses of all other particles set to zero)
    Q_cold  the same for the walls at T_ref (negative: heat leaving the fluid)
    Nu_hot  Q_hot / (2 hot_half_width) * H / (kappa (T_hot - T_ref)); 1 = pure conduction across a
            linear profile
    T_outlet_mean / T_outlet_bulk   plain and mixing-cup (u_x-weighted) mean of the fluid temperature
            in the outflow zone x >= length - zone_layers dx
    u_bulk  mean u_x of the fluid, against the start-up Poiseuille solution `poiseuille_bulk`
    """

    def __init__(self, solver: sph.Solver, c: Channel):
        sc = solver.scene
        self.solver, self.c = solver, c
        self.fluid = sc.fluid_mask
        self.hot = channel.hot_wall_mask(sc.r, c.dx, c.wall_layers, c.length / 2, c.hot_half_width) & ~self.fluid
        self.cold = sc.wall_mask & ~self.hot
        mat = c.material
        fluid = jnp.asarray(self.fluid)

        def flux(state, nbrs, source):
            rate = solver.sweep_fn(heat.Conduction(mat.kappa, mat.c_p), nbrs, r=state.r, rho=state.rho, T=state.T,
                                   mass=jnp.where(source, state.mass, 0.0)).dTdt
            return jnp.sum(jnp.where(fluid, state.mass * mat.c_p * rate, 0.0))

        self._flux = jax.jit(flux)
        self._update = jax.jit(solver.neighbors.update)
        self._nbrs = None

    def _neighbors(self, r):
        """A neighbour list of `r`: the probe's own list, updated under jit (re-allocated on overflow)."""
        nbrs = None if self._nbrs is None else self._update(r, self._nbrs)
        if nbrs is None or bool(nbrs.did_buffer_overflow):
            nbrs = self.solver.neighbors.allocate(r)
        self._nbrs = nbrs
        return nbrs

    def __call__(self, t: float, state) -> dict:
        c, f = self.c, self.fluid
        nbrs = self._neighbors(state.r)
        q_hot = float(self._flux(state, nbrs, jnp.asarray(self.hot)))
        q_cold = float(self._flux(state, nbrs, jnp.asarray(self.cold)))
        r, T, u = np.asarray(state.r), np.asarray(state.T), np.asarray(state.u)
        outlet = f & (r[:, 0] >= c.length - max(c.zone_layers, 1) * c.dx)
        ux = u[outlet, 0]
        dT = c.T_hot - c.T_ref
        return {"time": t, "T_fluid_min": float(T[f].min()), "T_fluid_max": float(T[f].max()),
                "T_fluid_mean": float(T[f].mean()), "T_all_min": float(T.min()), "T_all_max": float(T.max()),
                "T_outlet_mean": float(T[outlet].mean()),
                "T_outlet_bulk": float(np.sum(ux * T[outlet]) / np.sum(ux)) if np.sum(ux) > 0 else float("nan"),
                "Q_hot": q_hot, "Q_cold": q_cold,
                "Nu_hot": q_hot / (2 * c.hot_half_width) * c.height / (c.material.kappa * dT),
                "u_max": float(np.linalg.norm(u[f], axis=1).max()), "u_bulk": float(u[f, 0].mean()),
                "u_bulk_exact": poiseuille_bulk(t, c.g, c.nu, c.height),
                "density_error": float(np.max(np.abs(np.asarray(state.rho)[f] / c.material.rho_ref - 1.0)))}


def channel_series(run: ChannelRun, traj: dict) -> pd.DataFrame:
    """`ChannelProbe`'s diagnostics of every frame of the run."""
    solver = sph.build_solver(*scene(run))
    probe = ChannelProbe(solver, run.channel)
    mass = jnp.asarray(solver.scene.particle_mass, solver.dtype)
    rows = []
    for t, r, u, rho, T in zip(traj["time"], traj["position"], traj["momentum_velocity"], traj["density"],
                               traj["temperature"]):
        state = FrameState(jnp.asarray(r), jnp.asarray(u), jnp.asarray(rho), jnp.asarray(T), mass)
        rows.append(probe(float(t), state))
    return pd.DataFrame(rows)


class FrameState(NamedTuple):
    """The fields of a stored frame that `ChannelProbe` reads (a pytree, as the solver's state)."""

    r: jnp.ndarray
    u: jnp.ndarray
    rho: jnp.ndarray
    T: jnp.ndarray
    mass: jnp.ndarray


def channel_row(run: ChannelRun, traj: dict) -> dict:
    c, meta = run.channel, traj["metadata"]
    s = channel_series(run, traj)
    end = s.iloc[-1]
    t_min, t_max = float(s["T_all_min"].min()), float(s["T_all_max"].max())
    violation = max(c.T_ref - t_min, t_max - c.T_hot, 0.0)
    n_steps = int(traj["attrs"]["n_steps"])
    wall = float(traj["attrs"]["wall_s"])
    dT = c.T_hot - c.T_ref
    row = {"case": "hot_channel", "dx": c.dx, "dtype": c.numerics.dtype, "n_particles": int(traj["particle_type"].shape[0]),
           "n_fluid": meta["n_fluid"], "n_steps": n_steps, "dt": meta["dt"], "t_end": float(end["time"]),
           "wall_s": wall, "compile_s": float(traj["attrs"]["compile_s"]),
           "ms_per_step": 1e3 * wall / n_steps if n_steps else np.nan,
           "T_fluid_min": float(s["T_fluid_min"].min()), "T_fluid_max": float(s["T_fluid_max"].max()),
           "theta_fluid_max": (float(s["T_fluid_max"].max()) - c.T_ref) / dT,
           "T_fluid_mean_end": float(end["T_fluid_mean"]), "T_outlet_mean_end": float(end["T_outlet_mean"]),
           "T_outlet_bulk_end": float(end["T_outlet_bulk"]),
           "theta_outlet_bulk_end": (float(end["T_outlet_bulk"]) - c.T_ref) / dT,
           "Q_hot_end": float(end["Q_hot"]), "Q_cold_end": float(end["Q_cold"]), "Nu_hot_end": float(end["Nu_hot"]),
           "u_max_end": float(end["u_max"]), "u_bulk_end": float(end["u_bulk"]),
           "u_bulk_exact_end": float(end["u_bulk_exact"]),
           "u_bulk_relerr_end": float(end["u_bulk"] / end["u_bulk_exact"] - 1.0),
           "density_error_max": float(s["density_error"].max()), "density_error_end": float(end["density_error"]),
           "T_all_min": t_min, "T_all_max": t_max, "max_principle_violation": violation,
           "max_principle_ok": bool(violation <= c.max_principle_tol)}
    check_maximum_principle(row, c)
    return row


def check_maximum_principle(row: dict, c: Channel) -> None:
    """Raise if any temperature left [T_ref, T_hot] by more than max_principle_tol."""
    if not row["max_principle_ok"]:
        raise RuntimeError(
            f"hot channel: temperature left [T_ref, T_hot] = [{c.T_ref}, {c.T_hot}] by "
            f"{row['max_principle_violation']:.3g} > tol {c.max_principle_tol:g} (min {row['T_all_min']!r}, "
            f"max {row['T_all_max']!r}): the discrete maximum principle is violated")


