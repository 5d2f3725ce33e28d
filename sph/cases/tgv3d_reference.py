"""The 3D Taylor-Green vortex against its reference: the JAX-Fluids grid solution of
validation_refs/tgv3d_ref_<Re>.txt (PROVENANCE.md; Re 10, 20, 50, 100), E_kin(t) and -dE/dt(t) per
unit volume and density. Kept apart from sph.cases.tgv3d (the scene and its recipe) so that editing a
comparison re-runs nothing: a run's cache key covers the modules its scene imports.

  E_kin(t)   = sph.cases.tgv3d.e_kin_normalised(run's e_kin series)
  -dE/dt(t)  = -(E_{k+j} - E_{k-j}) / (t_{k+j} - t_{k-j})     central differences of the frames k +- j,
               j = max(1, round(dissipation_span / (2 frame spacing))), at the frames with j
               neighbours on both sides (second order; JAX-SPH used forward differences of neighbouring
               frames). A span of about one acoustic period or more filters the sound waves of the weakly
               compressible start (period 2 pi / (|k| c_ref) = 0.31 and 0.22 at c_ref = 10).

    ref = tgv3d_reference.reference(re=50)
    out = tgv3d_reference.compare(res.t, tgv3d.e_kin_normalised(res.e_kin), ref)   # dict of deviations
"""
from pathlib import Path

import numpy as np

from ..errors import ConfigError
from . import tgv3d

REFS = Path(__file__).resolve().parents[2] / "validation_refs"
"""The reference data of the repository (read by path)."""


def reference_path(re: float) -> Path:
    """validation_refs/tgv3d_ref_<re>.txt."""
    return REFS / f"tgv3d_ref_{re:g}.txt"


def load_reference(path, nu: float, u_ref: float = 1.0) -> dict:
    """JAX-Fluids reference (validation_refs/PROVENANCE.md): t, -dE/dt, E_kin per unit volume, from
    t = 0.01. The exact t = 0 values (E = U^2/8, -dE/dt = 3 nu U^2/4, sph.cases.tgv3d) are put in
    front, so that frames from t = 0 on interpolate without extrapolating."""
    path = Path(path)
    try:
        data = np.loadtxt(path, delimiter=",", ndmin=2)
    except (OSError, ValueError) as e:
        raise ConfigError(f"reference: cannot read {path} ({e})") from None
    if data.shape[1] != 3 or data.shape[0] < 2 or not np.all(np.isfinite(data)) or np.any(np.diff(data[:, 0]) <= 0):
        raise ConfigError(f"reference: {path} must hold rows t, -dE/dt, E_kin with increasing t, got shape {data.shape}")
    t = np.concatenate([[0.0], data[:, 0]])
    diss = np.concatenate([[tgv3d.dissipation_initial(nu, u_ref)], data[:, 1]])
    e = np.concatenate([[tgv3d.e_kin_initial(u_ref)], data[:, 2]])
    return {"t": t, "dissipation": diss, "e_kin": e, "path": path}


def reference(re: float, u_ref: float = 1.0) -> dict:
    """The reference at Reynolds number re (nu = u_ref L / re, L = 1): `load_reference`."""
    return load_reference(reference_path(re), u_ref / re, u_ref)


def stencil(t, span: float) -> int:
    """Frames j on either side of the central difference spanning about `span` in time (>= 1)."""
    spacing = (t[-1] - t[0]) / max(len(t) - 1, 1)
    return max(1, int(round(span / (2.0 * spacing)))) if spacing > 0 else 1


def energy_series(t, e_kin, dissipation_span: float = 0.5) -> dict:
    """t, E_kin (normalised: sph.cases.tgv3d.e_kin_normalised; all frames); t_mid, -dE/dt (central
    differences over +-j frames, at the frames that have j neighbours on both sides); j."""
    t, e = np.asarray(t, float), np.asarray(e_kin, float)
    j = stencil(t, dissipation_span)
    if t.shape[0] < 2 * j + 1:
        raise ValueError(f"tgv3d: {t.shape[0]} frames; -dE/dt by central differences over +-{j} frames "
                         f"(dissipation_span {dissipation_span:g}) needs at least {2 * j + 1}")
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


def deviations(ref: dict, s: dict, early_window: float = 1.0, u_ref: float = 1.0) -> dict:
    """Deviation of one run's series `s` (energy_series) from the reference over its frames within the
    reference's span (a run ends at the first step at or past t_end, up to one dt beyond it: 10.0031
    at 20^3; the frames past the reference's last time are left out): E_kin at t = 0 (exact U^2 / 8)
    and at the end, RMS and largest deviations of E_kin and -dE/dt, the dissipation peak, and the
    early decay rate (least-squares slope over [0, early_window])."""
    t_ref_end = float(ref["t"][-1]) * (1 + 1e-9)
    t, e = s["t"][s["t"] <= t_ref_end], s["e_kin"][s["t"] <= t_ref_end]
    tm, d = s["t_mid"][s["t_mid"] <= t_ref_end], s["dissipation"][s["t_mid"] <= t_ref_end]
    re, rd = reference_on(ref, t)["e_kin"], reference_on(ref, tm)["dissipation"]
    t_end = float(t[-1])
    ref_t, ref_h = reference_peak(ref, t_end)
    k = int(np.argmax(d))
    window = min(early_window, t_end)
    out = {
        "e_kin_t0": float(e[0]), "e_kin_t0_relerr": float(e[0] / tgv3d.e_kin_initial(u_ref) - 1.0),
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


def compare(t, e_kin, ref: dict, dissipation_span: float = 0.5, early_window: float = 1.0,
            u_ref: float = 1.0) -> dict:
    """`deviations` of the normalised E_kin series (t, e_kin) from the reference `ref`."""
    return deviations(ref, energy_series(t, e_kin, dissipation_span), early_window, u_ref)
