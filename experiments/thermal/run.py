"""Run the thermal studies of a profile and collect their metrics.

sine     the heat operator against the analytical decay of T = T0 + A sin(k x) in the periodic unit
         square at rest (one run per dx):
           results/<profile>/thermal/sine_dx<dx>/series.csv     t, amplitude, exact, u_max per frame
           results/<profile>/thermal/sine_dx<dx>/metadata.json
           results/<profile>/thermal/sine_metrics.csv           one row per dx (upserted)
channel  JAX-SPH's hot channel (Fig. 10):
           results/<profile>/thermal/channel_dx<dx>/frames.npz  time, r, T, u of every particle per frame
           results/<profile>/thermal/channel_dx<dx>/series.csv  per-frame diagnostics (below)
           results/<profile>/thermal/channel_dx<dx>/metadata.json
           results/<profile>/thermal/channel_metrics.csv        one row (upserted)

A run whose outputs were made from the same inputs (fingerprint of its config section and of the
code) is skipped. The runs are short (seconds to a minute), so an interrupted run starts again.

The channel run checks the discrete maximum principle: every temperature stays within
[T_ref, T_hot] up to `max_principle_tol`; it raises after writing its outputs if not.

    python experiments/thermal/run.py --profile smoke [--results results/smoke] [--task sine|channel|all]
"""
import json
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pandas as pd

import sph
from sph import heat, simulate
from lab import cli, io, record, runs, tables
from sph.cases import channel
from lab.configtools import to_mapping
from sph.domain import Domain
from sph.lattice import cartesian
from sph.scene import Scene
from sph.state import FLUID
try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S


def init_state(solver: sph.Solver):
    """What `solver.init_fn()` returns, with the initial state built under jit (`solver.state_at`):
    the same numbers, but one compilation instead of several seconds of op-by-op dispatch."""
    r = jnp.asarray(solver.scene.r, solver.dtype)
    nbrs = solver.neighbors.allocate(r)
    return jax.jit(solver.state_at)(r, jnp.asarray(solver.scene.u, solver.dtype), nbrs), nbrs


def _is_current(folder: Path, fp: str, *files: str) -> bool:
    meta = folder / "metadata.json"
    if not meta.exists() or not all((folder / f).exists() for f in files):
        return False
    try:
        return json.loads(meta.read_text()).get("fingerprint") == fp
    except json.JSONDecodeError:
        return False


# == sine: heat operator vs the analytical decay ===================================================
def sine_scene(d: "S.Diffusion", dx: float) -> Scene:
    """Uniform lattice in the periodic unit square, at rest, T = T0 + A sin(k x)."""
    r = cartesian([0.0, 0.0], [1.0, 1.0], dx)
    T = d.T0 + d.amplitude * np.sin(d.k * r[:, 0])
    return Scene(name="heat_sine", dx=dx, domain=Domain(box=(1.0, 1.0), periodic=(True, True)),
                 material=d.material, effects=sph.Effects(heat=True), r=r, u=np.zeros_like(r),
                 tag=np.full(len(r), FLUID, np.int32), T=T)


def sine_amplitude(r, T, d: "S.Diffusion") -> float:
    """Projection of T - T0 on sin(k x): exact for the lattice mode (2/N sum_i (T_i - T0) sin(k x_i))."""
    r, T = np.asarray(r), np.asarray(T)
    return float(2.0 * np.mean((T - d.T0) * np.sin(d.k * r[:, 0])))


def run_sine(exp: "S.Experiment", dx: float, results, progress: bool = True) -> dict:
    d = exp.diffusion
    folder = S.sine_dir(results, dx)
    fp = S.sine_fingerprint(d, dx)
    if _is_current(folder, fp, "series.csv"):
        print(f"sine {S.dx_tag(dx)}: up to date, skipped", flush=True)
        return record_sine(exp, dx, results)
    solver = sph.build_solver(sine_scene(d, dx), d.numerics)
    state, nbrs = init_state(solver)
    r0 = np.asarray(state.r)
    n_steps = solver.n_steps(d.t_end)
    write_every = runs.write_every_for(n_steps, d.frames)
    frames = {"time": [0.0], "amplitude": [sine_amplitude(state.r, state.T, d)],
              "u_max": [float(jnp.max(jnp.linalg.norm(state.u, axis=1)))]}

    def on_frame(step, t, s):
        frames["time"].append(t)
        frames["amplitude"].append(sine_amplitude(s.r, s.T, d))
        frames["u_max"].append(float(jnp.max(jnp.linalg.norm(s.u, axis=1))))

    res = simulate.run(solver, state, nbrs, d.t_end, write_every, progress=progress, callback=on_frame,
                       desc=f"sine {S.dx_tag(dx)}")
    disp = np.asarray(res.state.r) - r0
    disp -= np.round(disp)  # minimum image in the unit box
    series = pd.DataFrame(frames)
    series["exact"] = d.amplitude_exact(series["time"])
    series["relerr"] = series["amplitude"] / series["exact"] - 1.0
    folder.mkdir(parents=True, exist_ok=True)
    series.to_csv(folder / "series.csv", index=False)
    io.write_metadata(folder / "metadata.json", {
        "case": "heat_sine", "dx": dx, "dt": solver.dt, "dt_limits": solver.dt_limits, "n_steps": res.step_end,
        "n_particles": solver.scene.n, "write_every": write_every, "wall_s": res.wall_s,
        "compile_s": res.compile_s, "peak_rss_mb": runs.peak_rss_mb(), "displacement_max": float(np.max(np.abs(disp))),
        "diffusion": to_mapping(d), "fingerprint": fp})
    row = record_sine(exp, dx, results)
    print(f"sine {S.dx_tag(dx)}: {res.n_steps} steps of {solver.scene.n} particles in {res.wall_s:.2f} s, "
          f"decay-rate error {100 * row['decay_rate_relerr']:+.3f} %, amplitude error at t = {d.t_end:g} "
          f"{100 * row['amplitude_relerr_tend']:+.3f} %", flush=True)
    return row


def sine_row(exp: "S.Experiment", dx: float, results) -> dict:
    d = exp.diffusion
    folder = S.sine_dir(results, dx)
    s = pd.read_csv(folder / "series.csv")
    meta = json.loads((folder / "metadata.json").read_text())
    t, a = s["time"].to_numpy(), s["amplitude"].to_numpy()
    rate_exact = d.alpha * d.k**2
    rate_sim = -np.polyfit(t, np.log(a / d.amplitude), 1)[0]  # least-squares slope of log A(t)
    n_steps = int(meta["n_steps"])
    return {"case": "heat_sine", "dx": dx, "dtype": d.numerics.dtype, "n_particles": meta["n_particles"],
            "n_steps": n_steps, "dt": meta["dt"], "dt_thermal": meta["dt_limits"].get("thermal", np.nan),
            "t_end": float(t[-1]), "alpha": d.alpha, "k": d.k,
            "wall_s": meta["wall_s"], "compile_s": meta["compile_s"],
            "ms_per_step": 1e3 * meta["wall_s"] / n_steps if n_steps else np.nan,
            "amplitude_ratio_sim": float(a[-1] / d.amplitude),
            "amplitude_ratio_exact": float(d.amplitude_exact(t[-1]) / d.amplitude),
            "amplitude_relerr_tend": float(s["relerr"].iloc[-1]),
            "amplitude_relerr_max": float(np.max(np.abs(s["relerr"]))),
            "decay_rate_sim": float(rate_sim), "decay_rate_exact": float(rate_exact),
            "decay_rate_relerr": float(rate_sim / rate_exact - 1.0),
            "motion_allowed": True,  # the full step runs: particles are free to move, but at rest on a
            "u_max_max": float(s["u_max"].max()),  # uniform periodic lattice every force cancels
            "displacement_max": meta["displacement_max"],
            "target_relerr": d.target_relerr,
            "meets_target": bool(max(abs(rate_sim / rate_exact - 1.0), abs(s["relerr"].iloc[-1])) <= d.target_relerr)}


def record_sine(exp, dx, results) -> dict:
    """The row of one sine run; sine_metrics.csv is rebuilt from every current run of the config."""
    row = sine_row(exp, dx, results)
    rows = [sine_row(exp, x, results) for x in exp.diffusion.dx
            if _is_current(S.sine_dir(results, x), S.sine_fingerprint(exp.diffusion, x), "series.csv")]
    tables.write_table(S.out_dir(results) / "sine_metrics.csv", rows, sort=["dx"], ascending=False)
    folder = S.sine_dir(results, dx)
    meta = io.read_metadata(folder / "metadata.json")
    record.save_record(folder, {**{k: np.nan for k in record.RECORD_COLUMNS},
                              "experiment": S.NAME, "target": "heat-validation", "method": "heat", "effects": "heat",
                              "kernel": exp.diffusion.numerics.kernel, "dx": dx, "dim": 2,
                              "dtype": exp.diffusion.numerics.dtype, "n_particles": row["n_particles"],
                              "n_steps": row["n_steps"], "dt": row["dt"], "t_end": row["t_end"],
                              "wall_s": row["wall_s"], "compile_s": row["compile_s"],
                              "ms_per_step": row["ms_per_step"], "peak_rss_mb": meta.get("peak_rss_mb", np.nan),
                              "err_decay_rate": abs(row["decay_rate_relerr"]),
                              "err_amplitude_tend": abs(row["amplitude_relerr_tend"])})
    return row


# == channel: JAX-SPH's hot channel (Fig. 10) ======================================================
def channel_scene(c: "S.Channel") -> Scene:
    return channel.scene(c.dx, c.material, c.effects, length=c.length, height=c.height, layers=c.wall_layers,
                         noise_factor=c.noise_factor, seed=c.seed, T_ref=c.T_ref, T_hot=c.T_hot,
                         hot_half_width=c.hot_half_width, zone_layers=c.zone_layers)


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

    def __init__(self, solver: sph.Solver, c: "S.Channel"):
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


def run_channel(exp: "S.Experiment", results, progress: bool = True, callback=None) -> dict:
    c = exp.channel
    folder = S.channel_dir(results, c.dx)
    fp = S.channel_fingerprint(c)
    if _is_current(folder, fp, "frames.npz", "series.csv"):
        print(f"channel {S.dx_tag(c.dx)}: up to date, skipped", flush=True)
        return record_channel(exp, results)
    solver = sph.build_solver(channel_scene(c), c.numerics)
    state, nbrs = init_state(solver)
    probe = ChannelProbe(solver, c)
    n_steps = solver.n_steps(c.t_end)
    write_every = runs.write_every_for(n_steps, c.frames)
    frames = {"time": [], "r": [], "T": [], "u": []}
    series = []

    def on_frame(step, t, s):
        frames["time"].append(t)
        frames["r"].append(np.asarray(s.r))
        frames["T"].append(np.asarray(s.T))
        frames["u"].append(np.asarray(s.u))
        series.append(probe(t, s))
        if callback is not None:
            callback(step, t, s)

    on_frame(0, 0.0, state)
    res = simulate.run(solver, state, nbrs, c.t_end, write_every, progress=progress, callback=on_frame,
                       desc=f"channel {S.dx_tag(c.dx)}",
                       u_limit=c.numerics.c_ref_factor * c.material.u_ref)
    folder.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(folder / "frames.npz", time=np.asarray(frames["time"]), r=np.stack(frames["r"]),
                        T=np.stack(frames["T"]), u=np.stack(frames["u"]), tag=np.asarray(solver.scene.tag),
                        hot=probe.hot, box=np.asarray(solver.scene.domain.box))
    pd.DataFrame(series).to_csv(folder / "series.csv", index=False)
    io.write_metadata(folder / "metadata.json", {
        "case": "hot_channel", "dx": c.dx, "dt": solver.dt, "dt_limits": solver.dt_limits,
        "n_steps": res.step_end, "n_particles": solver.scene.n, "n_fluid": int(probe.fluid.sum()),
        "n_hot_wall": int(probe.hot.sum()), "write_every": write_every, "wall_s": res.wall_s,
        "compile_s": res.compile_s, "n_reallocations": res.n_reallocations, "effects": c.effects.names(),
        "channel": to_mapping(c), "fingerprint": fp})
    row = record_channel(exp, results)
    print(f"channel {S.dx_tag(c.dx)}: {res.n_steps} steps of {solver.scene.n} particles in {res.wall_s:.2f} s "
          f"(compile {res.compile_s:.1f} s); T_fluid in [{row['T_fluid_min']:.6f}, {row['T_fluid_max']:.6f}], "
          f"outlet T {row['T_outlet_mean_end']:.5f}, Nu_hot {row['Nu_hot_end']:.3f}, "
          f"u_bulk error {100 * row['u_bulk_relerr_end']:+.2f} %", flush=True)
    check_maximum_principle(row, c)
    return row


def check_maximum_principle(row: dict, c: "S.Channel") -> None:
    """Raise if any temperature left [T_ref, T_hot] by more than max_principle_tol."""
    if not row["max_principle_ok"]:
        raise RuntimeError(
            f"hot channel: temperature left [T_ref, T_hot] = [{c.T_ref}, {c.T_hot}] by "
            f"{row['max_principle_violation']:.3g} > tol {c.max_principle_tol:g} (min {row['T_all_min']!r}, "
            f"max {row['T_all_max']!r}): the discrete maximum principle is violated")


def channel_row(exp: "S.Experiment", results) -> dict:
    c = exp.channel
    folder = S.channel_dir(results, c.dx)
    s = pd.read_csv(folder / "series.csv")
    meta = json.loads((folder / "metadata.json").read_text())
    end = s.iloc[-1]
    t_min, t_max = float(s["T_all_min"].min()), float(s["T_all_max"].max())
    violation = max(c.T_ref - t_min, t_max - c.T_hot, 0.0)
    n_steps = int(meta["n_steps"])
    dT = c.T_hot - c.T_ref
    return {"case": "hot_channel", "dx": c.dx, "dtype": c.numerics.dtype, "n_particles": meta["n_particles"],
            "n_fluid": meta["n_fluid"], "n_steps": n_steps, "dt": meta["dt"], "t_end": float(end["time"]),
            "wall_s": meta["wall_s"], "compile_s": meta["compile_s"],
            "ms_per_step": 1e3 * meta["wall_s"] / n_steps if n_steps else np.nan,
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


def record_channel(exp, results) -> dict:
    """The channel's row; channel_metrics.csv holds exactly the current config's channel run."""
    row = channel_row(exp, results)
    tables.write_table(S.out_dir(results) / "channel_metrics.csv", [row])
    return row


# == driver ========================================================================================
def run_all(exp: "S.Experiment", results, task: str = "all", dxs=None, progress: bool = True) -> dict:
    t0 = time.perf_counter()
    out = {}
    if task in ("sine", "all"):
        out["sine"] = [run_sine(exp, dx, results, progress) for dx in (exp.diffusion.dx if dxs is None else dxs)]
    if task in ("channel", "all"):
        out["channel"] = run_channel(exp, results, progress)
    print(f"thermal ({task}): done in {time.perf_counter() - t0:.1f} s -> {S.out_dir(results)}", flush=True)
    return out


def options(ap):
    ap.add_argument("--task", choices=("sine", "channel", "all"), default="all")
    ap.add_argument("--dx", nargs="*", type=float, default=None, help="sine: spacings to run (default: all)")
    ap.add_argument("--no-progress", action="store_true")


def main(args):
    exp = S.load(args.profile)
    dxs = cli.select("--dx", args.dx, list(exp.diffusion.dx))
    run_all(exp, args.results, args.task, dxs, not args.no_progress)


if __name__ == "__main__":
    from lab.cli import profile_main

    profile_main(main, __doc__, options)
