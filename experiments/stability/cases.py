"""Scenes, per-frame monitoring and the run of one stability case: everything that produces a case's
metrics (so this file, settings.py and sph/ are what a cached result's fingerprint covers; the
pass/fail evaluation and the table in run.py can change without re-running anything).

Monitor (after every diagnostic frame, the initial state included):

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
"""
import time
import traceback
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

import sph
from sph import simulate
from lab import io
from sph.cases import ldc, tank, tgv
from sph.domain import Domain
from sph.lattice import cartesian, jitter
from sph.scene import Scene
from sph.state import FLUID

LAYERS = 3  # wall layers of the tank and cavity scenes (their default)
EKIN_WINDOW = 0.2  # the TGV relative E_kin check covers frames with E_exact >= EKIN_WINDOW * E_exact(0)


# -- scenes -----------------------------------------------------------------------------------------
class Geometry:
    """What the monitor needs besides the state: the fluid box faces (walled cases), gravity, floor."""

    def __init__(self, lo=None, hi=None, g=0.0, floor=0.0, setup=""):
        self.lo, self.hi, self.g, self.floor, self.setup = lo, hi, g, floor, setup


def build_scene(case, progress: bool = True):
    """(Scene, Geometry, info) of a case (`settings.Case`)."""
    dx, mat, fx = case.dx, case.material, case.effects
    off = LAYERS * dx
    if case.kind == "dam_break":
        (w, h), (L, H) = case.column, case.tank
        scene = tank.scene(dx, mat, fx, width=w, height=h, tank_length=L, tank_height=H, layers=LAYERS)
        g = -float(fx.gravity[1])
        return scene, Geometry(np.array([off, off]), np.array([off + L, off + H]), g=g, floor=off,
                               setup=f"column {w:g}x{h:g} in tank {L:g}x{H:g}, g={g:g}"), {}
    if case.kind == "ldc":
        scene = ldc.scene(dx, mat, fx, layers=LAYERS, lid_velocity=case.lid_velocity)
        return scene, Geometry(np.array([off, off]), np.array([off + 1.0, off + 1.0]),
                               setup=f"Re={case.re:g}, lid u={case.lid_velocity:g}"), {}
    if case.kind == "tgv":
        r, info = tgv_positions(case, progress)
        scene = tgv.scene(dx, mat, fx, r=r)
        return scene, Geometry(setup=f"Re={case.re:g}, {info['start']}"), info
    # heat: periodic unit square at rest with a temperature sine or step along x
    r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
    x = r[:, 0]
    T = case.T0 + case.dT * (np.sin(2 * np.pi * x) if case.temperature == "sine" else (x < 0.5).astype(float))
    scene = Scene(name="heat", dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)), material=mat,
                  effects=fx, r=r, u=np.zeros_like(r), tag=np.full(len(r), FLUID, np.int32), T=T)
    alpha = mat.kappa / (mat.rho_ref * mat.c_p)
    return scene, Geometry(setup=f"T {case.temperature}, at rest, kappa={mat.kappa:g} (alpha={alpha:g})"), {}


def tgv_positions(case, progress: bool):
    """Initial TGV positions: the cell-centred lattice, a jittered lattice, or tgv2d's relaxation."""
    dx = case.dx
    r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
    if case.start == "lattice":
        return r, {"start": "lattice"}
    if case.start == "jitter":
        r = jitter(r, case.jitter * dx, case.seed, box=(1.0, 1.0))
        return np.where(r >= 1.0, 0.0, r), {"start": f"lattice + jitter {case.jitter:g} dx"}
    from sph.relax import relax

    rl = case.relaxation
    r = jitter(r, rl.noise_factor * dx, rl.seed, box=(1.0, 1.0))
    r = np.where(r >= 1.0, 0.0, r)
    t0 = time.perf_counter()
    scene = tgv.scene(dx, case.material, sph.Effects(tvf=True), r=r)
    r, info = relax(scene, case.numerics, rl, progress, desc=f"relax dx{dx:g}")
    how = f"relaxed {rl.steps} steps" + (f" (quench every {rl.quench_every})" if rl.quench_every else "")
    return r, {"start": how, "relax_s": time.perf_counter() - t0,
               "relax_density_error_end": info.get("density_error_end"), "relax_u_max_end": info.get("u_max_end")}


# -- monitoring -------------------------------------------------------------------------------------
class Monitor:
    """Per-frame checks of a run: the driver's callback, and called once on the initial state."""

    def __init__(self, case, scene: Scene, geo: Geometry, dt: float):
        self.case, self.scene, self.geo, self.dt = case, scene, geo, dt
        self.fluid = scene.fluid_mask
        self.box = np.asarray(scene.domain.box, float)
        self.periodic = np.asarray(scene.domain.periodic, bool)
        n_fluid = int(self.fluid.sum())
        self.crossed = np.zeros(n_fluid, bool)
        self.left = np.zeros(n_fluid, bool)
        self.rows = []
        self.mode = np.sin(2 * np.pi * scene.r[self.fluid, 0]) if case.kind == "heat" else None

    def __call__(self, step, t, state):
        self.observe(step, state)

    def observe(self, step, state):
        f = self.fluid
        r = np.asarray(state.r, np.float64)
        rf = r[f]
        rho = np.asarray(state.rho, np.float64)[f]
        v = np.asarray(state.v, np.float64)[f]
        m = np.asarray(state.mass, np.float64)[f]
        speed2 = np.sum(v**2, axis=1)
        row = {"step": int(step), "t": step * self.dt,
               "density_error": float(np.max(np.abs(rho / self.case.material.rho_ref - 1.0))),
               "u_max": float(np.sqrt(speed2.max())), "e_kin": 0.5 * float(np.sum(m * speed2))}
        out = np.any(~self.periodic & ((rf < 0) | (rf >= self.box)), axis=1)
        self.left |= out
        row["n_outside"] = int(out.sum())
        if self.geo.lo is not None:
            tol = 0.5 * self.case.dx
            beyond = np.any((rf < self.geo.lo - tol) | (rf > self.geo.hi + tol), axis=1)
            self.crossed |= beyond | out
            row["n_beyond_wall"] = int(beyond.sum())
        row["min_spacing_dx"] = self._min_spacing(r, f) / self.case.dx
        if self.case.kind == "dam_break":
            row["e_pot"] = float(np.sum(m * self.geo.g * (rf[:, 1] - self.geo.floor)))
            row["energy"] = row["e_kin"] + row["e_pot"]
        elif self.case.kind == "tgv":
            row["e_kin_exact"] = float(tgv.e_kin_exact(row["t"], self.case.re)) * self.case.material.u_ref**2
        elif self.case.kind == "heat":
            T = np.asarray(state.T, np.float64)[f]
            row["energy"] = float(np.sum(m * self.case.material.c_p * T))
            row["T_min"], row["T_max"] = float(T.min()), float(T.max())
            row["mode_amplitude"] = float(2.0 * np.mean((T - T.mean()) * self.mode))
        self.rows.append(row)

    def _min_spacing(self, r, f):
        if np.all(self.periodic):
            r = np.mod(r, self.box)
            r = np.where(r >= self.box, 0.0, r)
            tree = cKDTree(r, boxsize=self.box)
        else:
            tree = cKDTree(r)
        d, _ = tree.query(r[f], k=2)
        return float(d[:, 1].min())

    def series(self) -> pd.DataFrame:
        return pd.DataFrame(self.rows)

    def summary(self) -> dict:
        """Metrics over all observed frames."""
        s = self.series()
        case, kind = self.case, self.case.kind
        out = {"density_error_max": float(s["density_error"].max()),
               "n_crossed_wall": int(self.crossed.sum()) if self.geo.lo is not None else 0,
               "n_left_domain": int(self.left.sum()),
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
            out["rest_speed"] = float(s["u_max"].to_numpy()[late].max() / np.sqrt(self.geo.g * case.column[1]))
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


# -- one run ----------------------------------------------------------------------------------------
class ThinWriter(io.TrajectoryWriter):
    """Stores every `store_every`-th frame the driver hands over (the first included) but, like the
    base writer, overwrites the checkpoint after every frame, so the last good state is always kept."""

    store_every = 1
    _seen = 0
    _last_stored = -1

    def append(self, state, step, t, diag=None):
        if self._seen % self.store_every == 0:
            super().append(state, step, t, diag)
            self._last_stored = step
        self._seen += 1

    def append_final(self, state, step, t):
        if self._last_stored != step:
            super().append(state, step, t)
            self._last_stored = step


def binding_limit(solver) -> str:
    """Name of the time-step limit that sets dt ("fixed" for numerics.dt)."""
    if solver.numerics.dt is not None:
        return "fixed"
    lim = {k: v for k, v in solver.dt_limits.items() if k != "dt"}
    return min(lim, key=lim.get)


def method_name(fx: sph.Effects) -> str:
    names = fx.names()
    core = [n for n in names if not n.startswith(("gravity", "walls"))]
    if not (fx.tvf or fx.riemann):
        core.insert(0, "sph")
    walls = [n.split("=")[1] for n in names if n.startswith("walls")]
    return "+".join(core) + (f" [{walls[0]} walls]" if walls else "")


def checkpoint_info(traj: Path) -> dict:
    """Step and time of the checkpoint in traj.h5 and whether every float field of it is finite."""
    try:
        state, step, attrs = io.load_checkpoint(traj)
    except (OSError, KeyError) as e:
        return {"checkpoint_step": -1, "checkpoint_t": np.nan, "checkpoint_finite": False,
                "checkpoint_error": str(e)}
    arrays = [np.asarray(getattr(state, n)) for n in state.field_names()]
    finite = all(np.all(np.isfinite(a)) for a in arrays if np.issubdtype(a.dtype, np.floating))
    return {"checkpoint_step": int(step), "checkpoint_t": float(attrs.get("t", np.nan)),
            "checkpoint_finite": bool(finite)}


def simulate_case(name: str, case, folder: Path, fingerprint: str = "", progress: bool = True):
    """Run one case into `folder` (traj.h5, series.csv). Returns (metrics, info). Never raises for a
    failing simulation: the driver's blow-up stop gives status "blew_up" with its message (step, time,
    particle), any other exception status "error" with its message (traceback in info)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    traj = folder / "traj.h5"
    if traj.exists():
        traj.unlink()
    metrics = {"case": name, "kind": case.kind, "method": method_name(case.effects), "setup": "",
               "dx": case.dx, "t_end": case.t_end, "message": ""}
    info, monitor = {}, None
    t_start = time.perf_counter()
    try:
        scene, geo, extra = build_scene(case, progress)
        info.update(extra)
        metrics["setup"] = geo.setup
        solver = sph.build_solver(scene, case.numerics)
        n_steps = solver.n_steps(case.t_end)
        write_every = max(1, int(round(n_steps / case.frames)))
        metrics.update(n_fluid=int(scene.fluid_mask.sum()), n_particles=scene.n, dt=solver.dt,
                       dt_binding=binding_limit(solver), n_steps=n_steps, write_every=write_every)
        info["dt_limits"] = {k: float(v) for k, v in solver.dt_limits.items()}
        monitor = Monitor(case, scene, geo, solver.dt)
        state, nbrs = solver.init_fn()
        if case.kind == "dam_break" and case.hydrostatic_init:
            state = tank.hydrostatic(state, solver.eos, case.material.rho_ref, geo.g, geo.floor + case.column[1])
        monitor.observe(0, state)
        writer = ThinWriter.create(traj, scene.tag, scene.dim, dtype=solver.dtype, keep=("velocity", "density"),
                                   attrs={"fingerprint": fingerprint, "case": name})
        writer.store_every = max(1, int(round(-(-n_steps // write_every) / case.stored_frames)))
        with writer:
            try:
                res = simulate.run(solver, state, nbrs, case.t_end, write_every, writer=writer, progress=progress,
                                   desc=name, callback=monitor,
                                   u_limit=case.numerics.c_ref_factor * case.material.u_ref)
                writer.append_final(res.state, res.step_end, res.step_end * solver.dt)
                writer.mark_complete(wall_s=res.wall_s, compile_s=res.compile_s, n_steps=res.n_steps)
                metrics.update(status="completed", finite_throughout=True, solve_s=res.wall_s,
                               compile_s=res.compile_s, ms_per_step=res.ms_per_step)
            except RuntimeError as e:  # the driver's blow-up stop
                msg = str(e)
                metrics.update(status="blew_up", message=msg, finite_throughout="non-finite" not in msg)
    except Exception as e:  # anything else (bad setup, a bug): record it, never stop the suite
        metrics.update(status="error", message=f"{type(e).__name__}: {e}", finite_throughout=False)
        info["traceback"] = traceback.format_exc()
    metrics["wall_s"] = time.perf_counter() - t_start
    if monitor is not None and monitor.rows:
        metrics.update(monitor.summary())
        monitor.series().to_csv(folder / "series.csv", index=False)
    if traj.exists():
        metrics.update(checkpoint_info(traj))
    return metrics, info
