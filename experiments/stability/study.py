"""The stability suite (experiments/stability/README.md) as a study of the protocol (lab.experiment):
a matrix of hard cases, each run to its end time by the harness and measured after every diagnostic
frame; plot_stability.py judges each case against the criteria written next to it (stability.csv,
stability.md). A case that blows up or cannot be built is an outcome, never a failed make
(FAILURES = "record": the harness keeps the error in the run's failure.json, and the frames up to the
last good state with their checkpoint in traj.h5).

A profile is `{inherit?, defaults, cases}`: `cases` maps a case name to its settings, `defaults` is
merged under every case (key by key, so a case overrides single numerics or criteria keys), and
`inherit: <profile>` merges the whole profile over another one, so the smoke profile only names what
it shrinks. An unknown or mistyped key fails with a message naming it, e.g.
"profiles.smoke.cases.ldc_tvf.t_edn: unknown key".

What a case measures (`metrics`, from every frame of its trajectory; `series` per frame):

  density_error_max   max |rho/rho_ref - 1| over fluid particles and frames
  n_crossed_wall      fluid particles ever found beyond a wall face by more than dx/2 (walled cases;
                      faces = the fluid box of the tank / cavity), or outside the box
  n_left_domain       fluid particles ever found outside the simulation box in a non-periodic dimension
  min_spacing_dx      smallest distance from a fluid particle to any other particle, / dx (clumping)
  u_max_max           largest fluid speed (transport velocity v)
  energy_*            dam break: E = E_kin + E_pot, E_pot = sum m g (y - floor) (dissipated): the largest
                      rise max_t (E(t) - min_{s<=t} E(s)) / E0 and E(t_end)/E0 - 1;
                      TGV: |E_kin / E_exact - 1|, max while E_exact >= 0.2 E0 (EKIN_WINDOW), and
                      (E_kin - E_exact) / E0 at the end; ekin_rise_max = max (E_kin(t) - min_{s<=t}
                      E_kin(s)) / E0, kinetic energy the decaying vortex gains (a collapse, spurious motion);
                      heat: sum m c_p T (conserved): max |E/E0 - 1| and at the end
  accuracy            TGV: |E_kin / E_exact - 1| at t = min(1, t_end);
                      heat: first Fourier mode of T over exp(-alpha (2 pi)^2 t), minus 1, at t_end

A case's key is its simulation settings (`criteria`, `expected` and `note` only judge a result: editing
them re-evaluates the table without re-running) and the code of this file with the sph modules it imports.
"""
import dataclasses
from dataclasses import dataclass, field
from typing import Optional

import h5py
import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

import sph
from lab import io
from lab.configtools import ConfigError, from_mapping, merge, require, require_finite, require_name
from lab.protocol import Start, Table
from sph.cases import ldc, tank, tgv
from sph.domain import Domain
from sph.lattice import cartesian, jitter
from sph.relax import Relaxation, relax
from sph.scene import Scene
from sph.state import FLUID

KINDS = ("dam_break", "ldc", "tgv", "heat")
STARTS = ("lattice", "jitter", "relaxed")
TEMPERATURES = ("sine", "step")
EXPECTED = ("pass", "fail", "unknown")
LAYERS = 3  # wall layers of the tank and cavity scenes (their default)
EKIN_WINDOW = 0.2  # the TGV relative E_kin check covers frames with E_exact >= EKIN_WINDOW * E_exact(0)
TABLE = Table(rows="metrics")
FAILURES = "record"
"""A case that raises (the driver's blow-up stop, a scene that cannot be built) is a result (lab.experiment)."""
JUDGED = {"metadata": {"key": False}}
"""A field that only judges a result: out of the run's key."""


@dataclass(frozen=True)
class Criteria:
    """Pass/fail thresholds of a case. A case passes when its fields stay finite to t_end (always
    required) and every check that is set holds; null switches a check off.

    density_error_max   max over fluid particles and frames of |rho/rho_ref - 1|
    no_crossing         no fluid particle ever beyond a wall face by more than dx/2, or outside the box
    energy_rise_max     dam break: max over frames of (E(t) - min_{s <= t} E(s)) / E(0), E = E_kin + E_pot
                        (dissipated: it may rise only by what the compressed fluid gives back)
    ekin_relerr_max     TGV: max over frames of |E_kin / E_kin_exact - 1| while E_kin_exact >= 0.2 E_kin_exact(0)
                        (t <= 1 at Re = 100; later the decayed vortex makes the ratio meaningless)
    ekin_rise_max       TGV: max over frames of (E_kin(t) - min_{s <= t} E_kin(s)) / E_kin_exact(0): the
                        decaying vortex must not gain kinetic energy (lattice collapse, spurious motion)
    thermal_drift_max   heat: max over frames of |E_th / E_th(0) - 1|, E_th = sum m c_p T
    overshoot_max       heat: largest excursion of T beyond its initial [min, max] / (max - min)
    dt_limit            the time-step limit that must be the binding one (e.g. "thermal"), or null
    rest_speed_max      tank at rest (a dam_break case whose column fills the tank's width): max |u| of
                        the fluid over the last quarter of the run / sqrt(g H), H the column height
    """

    density_error_max: Optional[float] = 0.05
    no_crossing: bool = True
    energy_rise_max: Optional[float] = None
    ekin_relerr_max: Optional[float] = None
    ekin_rise_max: Optional[float] = None
    thermal_drift_max: Optional[float] = None
    overshoot_max: Optional[float] = None
    dt_limit: Optional[str] = None
    rest_speed_max: Optional[float] = None


@dataclass(frozen=True)
class Case:
    """One stability case, a run of the suite (see config.yaml for the meaning of each key); its name
    is its folder."""

    name: str
    kind: str
    dx: float
    t_end: float
    effects: sph.Effects = field(default_factory=sph.Effects)
    material: sph.Material = field(default_factory=sph.Material)
    numerics: sph.Numerics = field(default_factory=sph.Numerics)
    criteria: Criteria = field(default_factory=Criteria, **JUDGED)
    expected: str = field(default="pass", **JUDGED)
    note: str = field(default="", **JUDGED)
    frames: int = 200  # diagnostic frames (each stored and checked); write_every = n_steps / frames
    # dam break: water column (width, height) in a tank (length, height); gravity from effects.gravity
    column: tuple[float, float] = (2.0, 1.0)
    tank: tuple[float, float] = (5.366, 2.0)
    hydrostatic_init: bool = True  # start from p = rho g (H - y) (sph.cases.tank.hydrostatic), as make fig8
    # lid-driven cavity
    lid_velocity: float = 1.0
    # Taylor-Green vortex: initial positions
    start: str = "lattice"
    jitter: float = 0.0
    seed: int = 0
    relaxation: Relaxation = field(default_factory=Relaxation)
    # heat: T = T0 + dT sin(2 pi x) ("sine") or T0 + dT for x < 1/2 ("step"), fluid at rest
    temperature: str = "sine"
    T0: float = 1.0
    dT: float = 1.0

    def __post_init__(self):
        require_finite(self)
        require(self.kind in KINDS, "kind", f"{self.kind!r} is not one of {KINDS}")
        require(self.dx > 0, "dx", f"must be positive, got {self.dx}")
        require(self.t_end > 0, "t_end", f"must be positive, got {self.t_end}")
        require(self.expected in EXPECTED, "expected", f"{self.expected!r} is not one of {EXPECTED}")
        require(self.frames >= 1, "frames", f"must be >= 1, got {self.frames}")
        require(self.start in STARTS, "start", f"{self.start!r} is not one of {STARTS}")
        require(self.jitter >= 0, "jitter", f"must be >= 0, got {self.jitter}")
        require(self.temperature in TEMPERATURES, "temperature", f"{self.temperature!r} is not one of {TEMPERATURES}")
        fx = self.effects
        if self.kind in ("tgv", "heat"):
            require(abs(1.0 / self.dx - round(1.0 / self.dx)) < 1e-6, "dx",
                    f"must divide the periodic unit square into whole cells (1/dx integer), got {self.dx}")
            require(fx.walls is None and fx.gravity is None, "effects",
                    f"a {self.kind} case is a periodic box without walls or gravity")
        if self.kind in ("dam_break", "ldc"):
            require(fx.walls is not None, "effects.walls", f"a {self.kind} case needs walls (no_slip or free_slip)")
        if self.kind == "dam_break":
            require(fx.gravity is not None and len(fx.gravity) == 2 and fx.gravity[1] < 0 and fx.gravity[0] == 0,
                    "effects.gravity", "the dam break needs gravity [0, -g] with g > 0")
            require(self.column[0] <= self.tank[0] and self.column[1] <= self.tank[1], "column",
                    f"the water column {self.column} does not fit into the tank {self.tank}")
        require(self.kind == "heat" or not fx.heat, "effects.heat", "only the heat case carries a temperature")
        if self.kind == "heat":
            require(fx.heat, "effects.heat", "the heat case needs effects.heat: true")
            require(self.dT > 0, "dT", f"must be positive, got {self.dT}")

    @property
    def re(self) -> float:
        """rho_ref u_ref L / eta with L = 1 (TGV box, cavity side)."""
        m = self.material
        return m.rho_ref * m.u_ref / m.eta if m.eta > 0 else float("inf")

    @property
    def method(self) -> str:
        return method_name(self.effects)


@dataclass(frozen=True)
class Settings:
    """One profile of config.yaml: `defaults` merged under every entry of `cases` (case name -> its
    settings; `name: null` in an inheriting profile drops the case), parsed into `Case`s on construction."""

    cases: dict
    defaults: dict = field(default_factory=dict)

    def __post_init__(self):
        require(len(self.cases) > 0, "cases", "no cases")
        parsed = []
        for name, spec in self.cases.items():
            if spec is None:
                continue
            if not isinstance(spec, dict):
                raise ConfigError(f"cases.{name}: expected a mapping, got {spec!r}")
            require_name(str(name), f"cases.{name}")  # the case's folder name
            if "name" in spec:
                raise ConfigError(f"cases.{name}.name: unknown key (a case's name is its key under cases)")
            parsed.append(from_mapping(Case, {"name": str(name), **merge(self.defaults, spec)}, f"cases.{name}"))
        object.__setattr__(self, "_cases", tuple(parsed))

    def names(self) -> list:
        return [c.name for c in self._cases]

    def case(self, name: str) -> Case:
        for c in self._cases:
            if c.name == name:
                return c
        raise KeyError(f"no case {name!r} (cases: {', '.join(self.names())})")


def runs(s: Settings) -> list:
    """The cases of the profile, in config order."""
    return list(s._cases)


# -- what a case builds -------------------------------------------------------------------------
@dataclass(frozen=True)
class Geometry:
    """What the checks need besides the frames: the fluid box faces (walled cases), gravity, floor."""

    lo: Optional[tuple] = None
    hi: Optional[tuple] = None
    g: float = 0.0
    floor: float = 0.0
    setup: str = ""


def geometry(case: Case) -> Geometry:
    fx, off = case.effects, LAYERS * case.dx
    if case.kind == "dam_break":
        (w, h), (L, H) = case.column, case.tank
        g = -float(fx.gravity[1])
        return Geometry((off, off), (off + L, off + H), g=g, floor=off,
                        setup=f"column {w:g}x{h:g} in tank {L:g}x{H:g}, g={g:g}")
    if case.kind == "ldc":
        return Geometry((off, off), (off + 1.0, off + 1.0), setup=f"Re={case.re:g}, lid u={case.lid_velocity:g}")
    if case.kind == "tgv":
        return Geometry(setup=f"Re={case.re:g}, {start_text(case)}")
    alpha = case.material.kappa / (case.material.rho_ref * case.material.c_p)
    return Geometry(setup=f"T {case.temperature}, at rest, kappa={case.material.kappa:g} (alpha={alpha:g})")


def start_text(case: Case) -> str:
    if case.start == "lattice":
        return "lattice"
    if case.start == "jitter":
        return f"lattice + jitter {case.jitter:g} dx"
    rl = case.relaxation
    return f"relaxed {rl.steps} steps" + (f" (quench every {rl.quench_every})" if rl.quench_every else "")


def start(case: Case) -> Optional[Start]:
    """A relaxed TGV case's start: tgv2d's relaxation (`relaxation`, TVF, quenched) of a jittered lattice."""
    if case.kind != "tgv" or case.start != "relaxed":
        return None
    rl, dx = case.relaxation, case.dx

    def compute(progress):
        r = jitter(cartesian([0.0, 0.0], [1.0, 1.0], dx), rl.noise_factor * dx, rl.seed, box=(1.0, 1.0))
        r = np.where(r >= 1.0, 0.0, r)
        scene = tgv.scene(dx, case.material, sph.Effects(tvf=True), r=r)
        return relax(scene, case.numerics, rl, progress, desc=f"relax dx{dx:g}")

    return Start(case.name, {"dx": dx, "material": case.material, "numerics": case.numerics, "relaxation": rl},
                 compute, meta={"dx": dx, "relaxation": dataclasses.asdict(rl)})


def scene(case: Case, r: Optional[np.ndarray] = None):
    """(Scene, Numerics) of a case; `r`: a relaxed TGV case's start (`start`)."""
    dx, mat, fx = case.dx, case.material, case.effects
    if case.kind == "dam_break":
        (w, h), (L, H) = case.column, case.tank
        sc = tank.scene(dx, mat, fx, width=w, height=h, tank_length=L, tank_height=H, layers=LAYERS)
    elif case.kind == "ldc":
        sc = ldc.scene(dx, mat, fx, layers=LAYERS, lid_velocity=case.lid_velocity)
    elif case.kind == "tgv":
        if r is None:
            r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
            if case.start == "jitter":
                r = jitter(r, case.jitter * dx, case.seed, box=(1.0, 1.0))
                r = np.where(r >= 1.0, 0.0, r)
        sc = tgv.scene(dx, mat, fx, r=r)
    else:  # heat: periodic unit square at rest with a temperature sine or step along x
        r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
        sc = Scene(name="heat", dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)), material=mat,
                   effects=fx, r=r, u=np.zeros_like(r), tag=np.full(len(r), FLUID, np.int32), T=heat_T(case, r))
    return sc, case.numerics


def heat_T(case: Case, r) -> np.ndarray:
    x = r[:, 0]
    return case.T0 + case.dT * (np.sin(2 * np.pi * x) if case.temperature == "sine" else (x < 0.5).astype(float))


def initial_state(case: Case, solver):
    """The solver's initial state; a dam break's started hydrostatic (`hydrostatic_init`)."""
    state, nbrs = solver.init_fn()
    if case.kind == "dam_break" and case.hydrostatic_init:
        geo = geometry(case)
        state = tank.hydrostatic(state, solver.eos, case.material.rho_ref, geo.g, geo.floor + case.column[1])
    return state, nbrs


def run_options(case: Case) -> dict:
    """Every frame keeps what the checks read; the driver stops a case faster than c_ref."""
    keep = ("velocity", "density") + (("temperature",) if case.kind == "heat" else ())
    return {"case": case.name, "keep": keep, "u_limit": case.numerics.c_ref_factor * case.material.u_ref}


# -- what a case measures ------------------------------------------------------------------------
def method_name(fx: sph.Effects) -> str:
    names = fx.names()
    core = [n for n in names if not n.startswith(("gravity", "walls"))]
    if not (fx.tvf or fx.riemann):
        core.insert(0, "sph")
    walls = [n.split("=")[1] for n in names if n.startswith("walls")]
    return "+".join(core) + (f" [{walls[0]} walls]" if walls else "")


def binding_limit(meta: dict) -> str:
    """Name of the time-step limit that set dt ("fixed" for numerics.dt), from the run's metadata."""
    if (meta.get("numerics") or {}).get("dt") is not None:
        return "fixed"
    lim = {k: v for k, v in meta["dt_limits"].items() if k != "dt"}
    return min(lim, key=lim.get)


def series(case: Case, traj: dict) -> tuple:
    """(per-frame checks as a DataFrame, fluid particles ever beyond a wall face or outside the box,
    fluid particles ever outside the box) of every stored frame."""
    geo = geometry(case)
    meta = traj["metadata"]
    fluid = traj["particle_type"] == FLUID
    box = np.array([hi for _, hi in meta["bounds"]], float)
    periodic = np.asarray(meta["periodic_boundary_conditions"], bool)
    mass = np.asarray(traj["mass"], np.float64)[fluid]
    crossed = np.zeros(int(fluid.sum()), bool)
    left = np.zeros(int(fluid.sum()), bool)
    mode = np.sin(2 * np.pi * cartesian([0.0, 0.0], [1.0, 1.0], case.dx)[fluid, 0]) if case.kind == "heat" else None
    lo = None if geo.lo is None else np.array(geo.lo)
    hi = None if geo.hi is None else np.array(geo.hi)
    rows = []
    for i, (step, t) in enumerate(zip(traj["step"], traj["time"])):
        r = np.asarray(traj["position"][i], np.float64)
        rf = r[fluid]
        rho = np.asarray(traj["density"][i], np.float64)[fluid]
        v = np.asarray(traj["velocity"][i], np.float64)[fluid]
        speed2 = np.sum(v**2, axis=1)
        row = {"step": int(step), "t": float(t),
               "density_error": float(np.max(np.abs(rho / case.material.rho_ref - 1.0))),
               "u_max": float(np.sqrt(speed2.max())), "e_kin": 0.5 * float(np.sum(mass * speed2))}
        out = np.any(~periodic & ((rf < 0) | (rf >= box)), axis=1)
        left |= out
        row["n_outside"] = int(out.sum())
        if lo is not None:
            tol = 0.5 * case.dx
            beyond = np.any((rf < lo - tol) | (rf > hi + tol), axis=1)
            crossed |= beyond | out
            row["n_beyond_wall"] = int(beyond.sum())
        row["min_spacing_dx"] = _min_spacing(r, fluid, box, periodic) / case.dx
        if case.kind == "dam_break":
            row["e_pot"] = float(np.sum(mass * geo.g * (rf[:, 1] - geo.floor)))
            row["energy"] = row["e_kin"] + row["e_pot"]
        elif case.kind == "tgv":
            row["e_kin_exact"] = float(tgv.e_kin_exact(row["t"], case.re)) * case.material.u_ref**2
        elif case.kind == "heat":
            T = np.asarray(traj["temperature"][i], np.float64)[fluid]
            row["energy"] = float(np.sum(mass * case.material.c_p * T))
            row["T_min"], row["T_max"] = float(T.min()), float(T.max())
            row["mode_amplitude"] = float(2.0 * np.mean((T - T.mean()) * mode))
        rows.append(row)
    return pd.DataFrame(rows), crossed, left


def _min_spacing(r, fluid, box, periodic) -> float:
    if np.all(periodic):
        r = np.mod(r, box)
        r = np.where(r >= box, 0.0, r)
        tree = cKDTree(r, boxsize=box)
    else:
        tree = cKDTree(r)
    d, _ = tree.query(r[fluid], k=2)
    return float(d[:, 1].min())


def summary(case: Case, s: pd.DataFrame, crossed, left) -> dict:
    """Metrics over all frames of `series`."""
    kind, geo = case.kind, geometry(case)
    out = {"density_error_max": float(s["density_error"].max()),
           "n_crossed_wall": int(crossed.sum()) if geo.lo is not None else 0,
           "n_left_domain": int(left.sum()),
           "min_spacing_dx": float(s["min_spacing_dx"].min()),
           "u_max_max": float(s["u_max"].max()),
           "t_reached": float(s["t"].iloc[-1]),
           "energy_quantity": "-", "energy_drift": np.nan, "energy_end": np.nan,
           "accuracy_quantity": "-", "accuracy": np.nan}
    if kind == "dam_break":
        e = s["energy"].to_numpy()
        out.update(energy_quantity="E=E_kin+E_pot: max (E(t)-min_{s<=t}E(s))/E0; E(t_end)/E0-1",
                   energy_drift=float(np.max(e - np.minimum.accumulate(e)) / e[0]),
                   energy_end=float(e[-1] / e[0] - 1.0))
        out["energy_rise_above_initial"] = float(np.max(e - e[0]) / e[0])
        t = s["t"].to_numpy()
        late = t >= 0.75 * t[-1]
        out["rest_speed"] = float(s["u_max"].to_numpy()[late].max() / np.sqrt(geo.g * case.column[1]))
    elif kind == "tgv":
        t, e, ex = s["t"].to_numpy(), s["e_kin"].to_numpy(), s["e_kin_exact"].to_numpy()
        window = ex >= EKIN_WINDOW * ex[0]
        out.update(energy_quantity=f"abs(E_kin/E_exact-1): max while E_exact>={EKIN_WINDOW:g}E0; "
                                   "(E_kin-E_exact)/E0 at end",
                   energy_drift=float(np.max(np.abs(e[window] / ex[window] - 1.0))),
                   energy_end=float((e[-1] - ex[-1]) / ex[0]))
        out["ekin_abserr_max"] = float(np.max(np.abs(e - ex)) / ex[0])
        out["ekin_rise_max"] = float(np.max(e - np.minimum.accumulate(e)) / ex[0])
        t_acc = min(1.0, t[-1])
        out.update(accuracy_quantity=f"abs(E_kin/E_exact-1) at t={t_acc:g}",
                   accuracy=float(abs(np.interp(t_acc, t, e) / np.interp(t_acc, t, ex) - 1.0)))
    elif kind == "heat":
        e = s["energy"].to_numpy()
        out.update(energy_quantity="E_th/E_th0-1, E_th = sum m c_p T: max abs; at end",
                   energy_drift=float(np.max(np.abs(e / e[0] - 1.0))), energy_end=float(e[-1] / e[0] - 1.0))
        lo0, hi0 = s["T_min"].iloc[0], s["T_max"].iloc[0]
        over = max(float(s["T_max"].max() - hi0), float(lo0 - s["T_min"].min()), 0.0)
        out["T_overshoot"] = over / (hi0 - lo0)
        mat = case.material
        alpha = mat.kappa / (mat.rho_ref * mat.c_p)
        a = s["mode_amplitude"].to_numpy()
        exact = np.exp(-alpha * (2 * np.pi) ** 2 * s["t"].to_numpy())
        out.update(accuracy_quantity="first Fourier mode of T / exp(-alpha k^2 t) - 1 at t_end",
                   accuracy=float(a[-1] / a[0] / exact[-1] - 1.0))
        out["mode_decay_relerr_max"] = float(np.max(np.abs(a / a[0] / exact - 1.0)))
    return out


def read_trajectory(path) -> dict:
    """Every dataset of the trajectory, and the particle masses of its checkpoint (constant) and its
    solve time, read as stored (numpy, in the file's precision)."""
    traj = io.read_trajectory(path)
    with h5py.File(path, "r") as f:
        ck = f["00000"].get("checkpoint")
        traj["mass"] = ck["mass"][...] if ck is not None else None
        traj["checkpoint_wall_s"] = float(ck.attrs.get("wall_s", np.nan)) if ck is not None else np.nan
    traj["path"] = str(path)
    return traj


def checkpoint_info(traj_path) -> dict:
    """Step and time of the checkpoint in traj.h5 and whether every float field of it is finite (read
    as stored)."""
    try:
        with h5py.File(traj_path, "r") as f:
            ck = f["00000"]["checkpoint"]
            arrays = [ck[n][...] for n in ck.keys()]
            step, t = int(ck.attrs["step"]), float(ck.attrs.get("t", np.nan))
    except (OSError, KeyError) as e:
        return {"checkpoint_step": -1, "checkpoint_t": np.nan, "checkpoint_finite": False,
                "checkpoint_error": str(e)}
    finite = all(np.all(np.isfinite(a)) for a in arrays if np.issubdtype(a.dtype, np.floating))
    return {"checkpoint_step": step, "checkpoint_t": t, "checkpoint_finite": bool(finite)}


def metrics(case: Case, traj: dict) -> dict:
    """One row of the table: the case, its outcome (completed / blew_up: the driver's stop, with its
    message / error: anything else), the run's numbers and `summary` of every frame. `traj` is the
    harness's (lab.experiment): a failed case's holds `failure` (and its frames, if it got to run)."""
    failure, meta = traj.get("failure"), traj.get("metadata")
    ran = "position" in traj  # the scene was built and the run started
    m = {"case": case.name, "kind": case.kind, "method": case.method, "setup": geometry(case).setup if ran else "",
         "dx": case.dx, "t_end": case.t_end, "message": ""}
    if ran:
        n_steps = int(round(meta["t_end"] / meta["dt"]))
        m.update(n_fluid=int(meta["n_fluid"]), n_particles=int(meta["num_particles_max"]), dt=float(meta["dt"]),
                 dt_binding=binding_limit(meta), n_steps=n_steps, write_every=int(meta["write_every"]))
    attrs = traj.get("attrs", {})
    if failure is None:
        solve, compile_s, steps = float(attrs["wall_s"]), float(attrs["compile_s"]), int(attrs["n_steps"])
        m.update(status="completed", finite_throughout=True, solve_s=solve, compile_s=compile_s,
                 ms_per_step=1e3 * solve / steps if steps else np.nan)
        m["wall_s"] = solve + compile_s
    elif ran and "RuntimeError" in failure.get("kinds", ()):  # the driver's blow-up stop
        msg = failure["message"]
        m.update(status="blew_up", message=msg, finite_throughout="non-finite" not in msg)
        m["wall_s"] = traj.get("checkpoint_wall_s", np.nan)  # the solve up to the last good frame
    else:
        m.update(status="error", message=f"{failure['error']}: {failure['message']}", finite_throughout=False)
        m["wall_s"] = np.nan
    if ran and len(traj["step"]):
        m.update(summary(case, *series(case, traj)))
        m.update(checkpoint_info(traj["path"]))
    return m


def record(case: Case, m: dict) -> dict:
    """The run record (lab.record): the case, its outcome and its largest density error; the suite's
    verdicts are plot_stability.py's table, not errors of a reference solution."""
    return {"errors": {}, "run": case.name, "kind": case.kind, "status": m["status"],
            "density_error_max": m.get("density_error_max", np.nan)}
