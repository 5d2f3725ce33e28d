"""What a dam-break run measures, from its trajectory, against the experiments (the harness's analysis
module, lab.experiment: editing it re-evaluates the runs, never re-runs them).

Per run (every column), `series`, one row per frame:

  t          simulation time = t sqrt(g/H) (g = H = 1)
  p_sensor   p / (rho g H) at the sensor on the inner face of the right wall at height sensor_height H:
             Shepard interpolation of the fluid pressures, sum_f p_f V_f W / sum_f V_f W with
             V_f = m_f / rho_f and the run's kernel; 0 while sum_f V_f W < wet_threshold (no fluid
             there; a fully wetted flat wall gives about 0.5)
  p_sensor_smooth  the same, centred running mean over smooth_window
  x_front    surge front / H: largest fluid x from the inner face of the left wall, + dx/2 (the
             particle's own extent, so that the column starts at its width)
  h_back     residual height / H at the back wall: highest fluid y with x < height_band, + dx/2
  density_error  max |rho/rho_ref - 1| over fluid particles (frame diagnostic of the run)
  n_outside  fluid particles more than dx/2 beyond a wall face (outside the tank interior)

and its row of results/<profile>/dambreak2d/metrics.csv (`metrics`):

  n_fluid, n_particles, n_steps, dt, t_end, write_every, n_frames, wall_s (solve, compile excluded),
  compile_s, ms_per_step, other_load (cores of other work while it was timed), n_reallocations,
  density_error_max       max over frames and fluid particles of |rho/rho_ref - 1|
  n_left_tank             fluid particles that were outside the tank interior in any frame
  pressure column (Buchner 2002; same rule for both: t_a = first time p >= peak_threshold, peak =
  max over [t_a, t_a + peak_window]):
    p_arrival_t, p_peak_t, p_peak and ref_p_arrival_t, ref_p_peak_t, ref_p_peak, p_peak_relerr
    (p_peak / ref - 1), p_peak_dt (t - t_ref), p_rms (RMS of p_sim - p_ref at the reference times
    within the run), p_rms_t0 / p_rms_t1 (its time range); the same with suffix _smooth for the
    history smoothed by a centred running mean over smooth_window (the raw frame values carry the
    acoustic noise of weakly compressible SPH)
  front column (Martin & Moyce 1952, at the reference times):
    front_relerr_max, front_relerr_mean   |x_sim / x_ref - 1| for t <= front_t_max
    height_abserr_max                     max |h_sim - h_ref| / H for 0 < t <= t_end
    front_t_shift, front_relerr_max_shifted   the delay of the experiment's time origin that
                                          minimises front_relerr_max (grid of 0.005 over [0, 0.5]),
                                          and that error: Martin & Moyce's clock starts with the
                                          release of the column, whose gate takes a finite time to
                                          clear it (README: why the raw front runs ahead)
"""
from pathlib import Path

import numpy as np
import pandas as pd

import sph
from lab import record as records
from lab.protocol import Table
from sph.kernels import make_kernel
from sph.precision import resolve

TARGET = "fig8"
TABLE = Table(rows="metrics")
REFS = Path(__file__).resolve().parents[2] / "validation_refs"
BUCHNER = REFS / "dambreak_pressure_buchner_2002.csv"
MM_FRONT = REFS / "dambreak_front_martin_moyce_1952.csv"
MM_HEIGHT = REFS / "dambreak_height_martin_moyce_1952.csv"


def load_ref(path) -> tuple[np.ndarray, np.ndarray]:
    """(t, value) of a two-column reference CSV, sorted by t (stable)."""
    df = pd.read_csv(path)
    t, y = df.iloc[:, 0].to_numpy(float), df.iloc[:, 1].to_numpy(float)
    order = np.argsort(t, kind="stable")
    return t[order], y[order]


# -- per-frame quantities -------------------------------------------------------------------------
def sensor_pressure(pos, p, rho, mass, fluid, point, kernel, wet_threshold: float, rho_ref: float = 1.0,
                    dtype: str = "float64") -> np.ndarray:
    """(T,) Shepard-interpolated fluid pressure at `point` for every frame (0 where dry). `rho`
    (T, N) may be None (density not kept): the volumes are then m / rho_ref. The kernel is evaluated
    in `dtype` (the run's precision), whatever JAX's x64 flag was before."""
    resolve(dtype)
    out = np.zeros(pos.shape[0])
    for k in range(pos.shape[0]):
        d = np.linalg.norm(pos[k][fluid] - point, axis=1)
        near = d < kernel.cutoff
        if not near.any():
            continue
        vol = mass[fluid][near] / (rho[k][fluid][near] if rho is not None else rho_ref)
        w = vol * np.asarray(kernel.w(d[near].astype(dtype)))
        total = w.sum()
        if total >= wet_threshold:
            out[k] = float(np.sum(w * p[k][fluid][near]) / total)
    return out


def front_and_height(pos, fluid, offset: float, dx: float, band: float) -> tuple[np.ndarray, np.ndarray]:
    """(T,) surge front and (T,) back-wall height, both from the tank's inner faces, + dx/2."""
    x = pos[:, fluid, 0] - offset
    y = pos[:, fluid, 1] - offset
    front = x.max(axis=1) + 0.5 * dx
    h = np.where(x < band, y, -np.inf).max(axis=1) + 0.5 * dx
    return front, np.where(np.isfinite(h), h, 0.0)


def outside_tank(pos, fluid, offset: float, dx: float, length: float, height: float) -> np.ndarray:
    """(T, n_fluid) bool: fluid particle more than dx/2 beyond a wall face of the tank interior."""
    x = pos[:, fluid, 0] - offset
    y = pos[:, fluid, 1] - offset
    tol = 0.5 * dx
    return (x < -tol) | (x > length + tol) | (y < -tol) | (y > height + tol)


# -- comparisons ----------------------------------------------------------------------------------
def first_peak(t, p, threshold: float, window: float) -> tuple[float, float, float]:
    """(t_a, t_peak, p_peak): t_a = first time p >= threshold (linearly interpolated), the peak is
    the maximum of p over [t_a, t_a + window]. NaNs when p never reaches the threshold."""
    t, p = np.asarray(t, float), np.asarray(p, float)
    above = np.flatnonzero(p >= threshold)
    if above.size == 0:
        return np.nan, np.nan, np.nan
    i = int(above[0])
    t_a = t[i] if i == 0 else t[i - 1] + (threshold - p[i - 1]) * (t[i] - t[i - 1]) / (p[i] - p[i - 1])
    sel = (t >= t_a) & (t <= t_a + window)
    j = np.flatnonzero(sel)[np.argmax(p[sel])]
    return float(t_a), float(t[j]), float(p[j])


def moving_average(t, y, window: float) -> np.ndarray:
    """Centred running mean of y over the frames within +-window/2 of each frame (0 = no smoothing)."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    if window <= 0:
        return y.copy()
    c = np.concatenate([[0.0], np.cumsum(y)])
    lo = np.searchsorted(t, t - 0.5 * window, side="left")
    hi = np.searchsorted(t, t + 0.5 * window, side="right")
    return (c[hi] - c[lo]) / (hi - lo)


def pressure_metrics(exp, t, p) -> dict:
    """First peak (raw and smoothed) and RMS deviation of the sensor history against Buchner."""
    t_ref, p_ref = load_ref(BUCHNER)
    rta, rtp, rpp = first_peak(t_ref, p_ref, exp.peak_threshold, exp.peak_window)
    within = (t_ref >= t[0]) & (t_ref <= t[-1])
    row = {"ref_p_arrival_t": rta, "ref_p_peak_t": rtp, "ref_p_peak": rpp,
           "p_rms_t0": float(t_ref[within][0]) if within.any() else np.nan,
           "p_rms_t1": float(t_ref[within][-1]) if within.any() else np.nan}
    for suffix, sig in (("", p), ("_smooth", moving_average(t, p, exp.smooth_window))):
        ta, tp, pp = first_peak(t, sig, exp.peak_threshold, exp.peak_window)
        rms = float(np.sqrt(np.mean((np.interp(t_ref[within], t, sig) - p_ref[within]) ** 2))) if within.any() else np.nan
        row.update({f"p_arrival_t{suffix}": ta, f"p_peak_t{suffix}": tp, f"p_peak{suffix}": pp,
                    f"p_peak_relerr{suffix}": pp / rpp - 1.0, f"p_peak_dt{suffix}": tp - rtp, f"p_rms{suffix}": rms})
    return row


def front_metrics(exp, t, front, height) -> dict:
    tf, xf = load_ref(MM_FRONT)
    sel = (tf <= exp.front_t_max) & (tf <= t[-1])
    rel = np.abs(np.interp(tf[sel], t, front) / xf[sel] - 1.0)
    shifts = np.arange(0.0, 0.5 + 1e-9, 0.005)
    shifted = [np.abs(np.interp(tf[sel] - d, t, front) / xf[sel] - 1.0).max() if rel.size else np.nan
               for d in shifts]
    k = int(np.nanargmin(shifted)) if rel.size else 0
    th, yh = load_ref(MM_HEIGHT)
    selh = (th > 0) & (th <= t[-1])
    dh = np.abs(np.interp(th[selh], t, height) - yh[selh])
    return {"front_relerr_max": float(rel.max()) if rel.size else np.nan,
            "front_relerr_mean": float(rel.mean()) if rel.size else np.nan,
            "front_n_ref": int(rel.size),
            "front_t_shift": float(shifts[k]) if rel.size else np.nan,
            "front_relerr_max_shifted": float(shifted[k]) if rel.size else np.nan,
            "height_abserr_max": float(dh.max()) if dh.size else np.nan}


# -- one run --------------------------------------------------------------------------------------
def series(exp, column, tr: dict) -> tuple[pd.DataFrame, int]:
    """Per-frame quantities of one run (see module doc) and the number of fluid particles that left
    the tank interior in any frame."""
    pos = tr["position"]
    fluid = tr["particle_type"] == sph.FLUID
    off, dx = exp.offset, exp.dx
    kernel = make_kernel(exp.numerics.kernel, exp.numerics.h_factor * dx, 2)
    mass = np.full(pos.shape[1], exp.fluid.rho_ref * dx**2)
    point = np.array([off + exp.tank.length, off + exp.sensor_height * column.height])
    p_scale = exp.fluid.rho_ref * exp.g * column.height
    p_s = sensor_pressure(pos, tr["pressure"], tr.get("density"), mass, fluid, point, kernel,
                          exp.wet_threshold, exp.fluid.rho_ref, exp.numerics.dtype) / p_scale
    front, h = front_and_height(pos, fluid, off, dx, exp.height_band)
    out = outside_tank(pos, fluid, off, dx, exp.tank.length, exp.tank.height)
    return pd.DataFrame({"t": tr["time"], "p_sensor": p_s,
                         "p_sensor_smooth": moving_average(tr["time"], p_s, exp.smooth_window),
                         "x_front": front / column.height,
                         "h_back": h / column.height, "density_error": tr["density_error"],
                         "n_outside": out.sum(axis=1)}), int(out.any(axis=0).sum())


def metrics(run, tr: dict) -> dict:
    """Metrics row of one finished run."""
    exp, column, meta, attrs = run.settings, run.column, tr["metadata"], tr["attrs"]
    df, n_left = series(exp, column, tr)
    n_steps = int(attrs["n_steps"])
    row = {"case": exp.case, "column": column.name, "width": column.width, "height": column.height,
           "dx": exp.dx, "dtype": exp.numerics.dtype, "walls": exp.effects.walls,
           "n_fluid": int(np.sum(tr["particle_type"] == sph.FLUID)), "n_particles": int(tr["particle_type"].size),
           "n_steps": n_steps, "dt": meta["dt"], "t_end": float(tr["time"][-1]), "write_every": meta["write_every"],
           "n_frames": int(tr["time"].size), **records.timing(attrs, n_steps),
           "n_reallocations": int(attrs["n_reallocations"]),
           "density_error_max": float(np.max(tr["density_error"])), "n_left_tank": n_left}
    t = df["t"].to_numpy()
    if column.name == exp.pressure_column:
        row.update(pressure_metrics(exp, t, df["p_sensor"].to_numpy()))
    if column.name == exp.front_column:
        row.update(front_metrics(exp, t, df["x_front"].to_numpy(), df["h_back"].to_numpy()))
    return row


def record(run, m: dict) -> dict:
    errors = {"density_max": m["density_error_max"]}
    for k in ("p_rms_smooth", "front_relerr_max", "front_relerr_mean", "height_abserr_max"):
        if k in m:
            errors[k] = m[k]
    return {"errors": errors}
