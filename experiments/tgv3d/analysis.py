"""Post-processing of the 3D Taylor-Green runs: E_kin(t) and -dE/dt(t) from the written frames, and
their deviation from the JAX-Fluids reference (the metrics row of one run).

Kept apart from run.py on purpose: the run fingerprint covers settings.py, run.py and the sph
modules they and the solver import, not this file, so changing a metric re-evaluates the stored
trajectories without re-running them (the paper profile takes hours).

  E_kin(t)   = (1/2) sum_i m_i |v_i|^2 / (rho_ref (2 pi)^3)   the writer's e_kin series (sph.diagnostics,
               transport velocity v) per unit volume and density, the reference's normalisation
  -dE/dt(t)  = -(E_{k+j} - E_{k-j}) / (t_{k+j} - t_{k-j})     central differences of the frames k +- j,
               j = max(1, round(analysis.dissipation_span / (2 frame spacing))), at the frames with j
               neighbours on both sides (second order; JAX-SPH used forward differences of neighbouring
               frames). The span filters the sound waves of the weakly compressible start (settings.Analysis).
"""
import h5py
import numpy as np

from sph.harness import io
from sph.cases import tgv3d

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def stencil(t, span: float) -> int:
    """Frames j on either side of the central difference spanning about `span` in time (>= 1)."""
    spacing = (t[-1] - t[0]) / max(len(t) - 1, 1)
    return max(1, int(round(span / (2.0 * spacing)))) if spacing > 0 else 1


def energy_series(exp: "S.Experiment", traj: dict) -> dict:
    """t, E_kin per unit volume (all frames); t_mid, -dE/dt (central differences over +-j frames,
    at the frames that have j neighbours on both sides); j."""
    t = np.asarray(traj["time"], float)
    e = np.asarray(traj["e_kin"], float) / (exp.material.rho_ref * tgv3d.SIDE**3)
    j = stencil(t, exp.analysis.dissipation_span)
    if t.shape[0] < 2 * j + 1:
        raise ValueError(f"{exp.case}: {t.shape[0]} frames; -dE/dt by central differences over +-{j} frames "
                         f"(analysis.dissipation_span {exp.analysis.dissipation_span:g}) needs at least {2 * j + 1}")
    diss = -(e[2 * j:] - e[:-2 * j]) / (t[2 * j:] - t[:-2 * j])
    return {"t": t, "e_kin": e, "t_mid": t[j:-j], "dissipation": diss, "stencil": j}


def reference_on(ref: dict, t) -> dict:
    """The reference interpolated (linearly) onto times `t` (0 <= t <= the reference's last time)."""
    t = np.asarray(t, float)
    if t.size and (t.min() < ref["t"][0] - 1e-12 or t.max() > ref["t"][-1] * (1 + 1e-9)):
        raise ValueError(f"reference covers t in [{ref['t'][0]:g}, {ref['t'][-1]:g}], asked for "
                         f"[{t.min():g}, {t.max():g}]")
    return {"e_kin": np.interp(t, ref["t"], ref["e_kin"]), "dissipation": np.interp(t, ref["t"], ref["dissipation"])}


def reference_peak(ref: dict, t_end: float) -> tuple:
    """(time, height) of the reference's largest -dE/dt within [0, t_end] (its file rows)."""
    inside = ref["t"] <= t_end * (1 + 1e-9)
    k = int(np.argmax(np.where(inside, ref["dissipation"], -np.inf)))
    return float(ref["t"][k]), float(ref["dissipation"][k])


def early_rate(t, e, window: float) -> float:
    """-dE/dt over t in [0, window]: minus the least-squares slope of E(t) there (averages out the
    acoustic oscillation of the weakly compressible start)."""
    sel = t <= window * (1 + 1e-9)
    return float(-np.polyfit(t[sel], e[sel], 1)[0])


def deviations(exp: "S.Experiment", ref: dict, s: dict) -> dict:
    """Deviation of one run's series `s` (energy_series) from the reference over its frames within the
    reference's span (a run ends at the first step at or past t_end, up to one dt beyond it: 10.0031
    at 20^3; the frames past the reference's last time are left out)."""
    t_ref_end = float(ref["t"][-1]) * (1 + 1e-9)
    t, e = s["t"][s["t"] <= t_ref_end], s["e_kin"][s["t"] <= t_ref_end]
    tm, d = s["t_mid"][s["t_mid"] <= t_ref_end], s["dissipation"][s["t_mid"] <= t_ref_end]
    re, rd = reference_on(ref, t)["e_kin"], reference_on(ref, tm)["dissipation"]
    t_end = float(t[-1])
    ref_t, ref_h = reference_peak(ref, t_end)
    k = int(np.argmax(d))
    window = min(exp.analysis.early_window, t_end)
    out = {
        "e_kin_t0": float(e[0]), "e_kin_t0_relerr": float(e[0] / tgv3d.e_kin_initial(exp.material.u_ref) - 1.0),
        "e_kin_end": float(e[-1]), "e_kin_end_relerr": float(e[-1] / re[-1] - 1.0),
        "e_kin_rms_dev": float(np.sqrt(np.mean((e - re) ** 2))), "e_kin_max_dev": float(np.max(np.abs(e - re))),
        "e_kin_rms_rel": float(np.sqrt(np.mean((e / re - 1.0) ** 2))),
        "dissipation_rms_dev": float(np.sqrt(np.mean((d - rd) ** 2))),
        "dissipation_max_dev": float(np.max(np.abs(d - rd))),
        "dissipation_rms_rel": float(np.sqrt(np.mean((d - rd) ** 2)) / ref_h),
        "peak_t": float(tm[k]), "peak_dissipation": float(d[k]), "ref_peak_t": ref_t, "ref_peak_dissipation": ref_h,
        "peak_t_err": float(tm[k] - ref_t), "peak_dissipation_relerr": float(d[k] / ref_h - 1.0),
        "dissipation_stencil": s["stencil"], "early_window": window, "early_rate": early_rate(t, e, window),
        "ref_early_rate": early_rate(ref["t"], ref["e_kin"], window),
    }
    out["early_rate_relerr"] = out["early_rate"] / out["ref_early_rate"] - 1.0
    return out


def read_series(path, traj: str = "00000") -> dict:
    """The per-frame scalar series of a trajectory (sph.simulate.SERIES: time, e_kin, ...), its attrs and
    the particle count, without reading the positions (0.6 GB per run at 50^3)."""
    try:
        with h5py.File(path, "r") as f:
            g = f[traj]
            out = {k: g[k][...] for k in io.SERIES if k in g}
            out["attrs"] = dict(g.attrs)
            out["n_particles"] = int(g["particle_type"].shape[0])
    except (OSError, KeyError) as e:
        raise OSError(f"{path}: cannot read trajectory {traj} ({e}); the file is damaged or incomplete: "
                      "re-run the experiment (run.py sets it aside and redoes the run)") from None
    return out


def metrics_row(exp: "S.Experiment", method: str, n: int, results, ref: dict = None) -> dict:
    """Metrics of one finished run, from its traj.h5 and metadata.json."""
    folder = S.run_dir(results, method, n)
    tr = read_series(folder / "traj.h5")
    meta = io.read_metadata(folder / "metadata.json")
    attrs = tr["attrs"]
    n_steps = int(attrs["n_steps"])
    row = {"case": exp.case, "method": method, "n_side": n, "dx": exp.dx(n), "dtype": exp.numerics.dtype,
           "start": exp.start, "n_particles": tr["n_particles"], "n_steps": n_steps,
           "dt": meta["dt"], "t_end": float(tr["time"][-1]), "write_every": meta["write_every"],
           "n_frames": int(tr["time"].shape[0]), "wall_s": float(attrs["wall_s"]),
           "compile_s": float(attrs["compile_s"]),
           "ms_per_step": 1e3 * float(attrs["wall_s"]) / n_steps if n_steps else np.nan,
           "n_reallocations": int(attrs["n_reallocations"])}
    row.update(deviations(exp, ref if ref is not None else S.load_reference(exp), energy_series(exp, tr)))
    row["density_error_max"] = float(np.max(tr["density_error"]))
    return row
