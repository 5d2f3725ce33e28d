"""Post-processing of the 3D Taylor-Green runs: E_kin(t) and -dE/dt(t) from the written frames, and
their deviation from the JAX-Fluids reference (the metrics row of one run).

The harness's analysis module (lab.experiment): the runs' keys cover study.py and the sph modules it
and the solver import, not this file, so changing a metric re-evaluates the stored trajectories
without re-running them (the paper profile takes hours).

The normalisation of E_kin (per unit volume and density, the reference's) is
sph.cases.tgv3d.e_kin_normalised; -dE/dt by central differences over `analysis.dissipation_span`, the
reference and the deviations from it are sph.cases.tgv3d_reference's (which a script uses alike).
"""
import h5py
import numpy as np

from lab import io, record as records
from lab.protocol import Table
from sph.cases import tgv3d
from sph.cases import tgv3d_reference as ref_mod

TARGET = "fig9"
TABLE = Table(rows="metrics", sort=("n_side", "method"))


def load_reference(exp) -> dict:
    """The JAX-Fluids reference of the profile (its reference_file), the exact t = 0 values in
    front (sph.cases.tgv3d_reference.load_reference)."""
    return ref_mod.load_reference(exp.reference_file, exp.nu, exp.material.u_ref)


def energy_series(exp, traj: dict) -> dict:
    """t, E_kin per unit volume (all frames); t_mid, -dE/dt (central differences over +-j frames,
    at the frames that have j neighbours on both sides); j (sph.cases.tgv3d_reference.energy_series)."""
    return ref_mod.energy_series(traj["time"], tgv3d.e_kin_normalised(traj["e_kin"], exp.material.rho_ref),
                                 exp.analysis.dissipation_span)


def deviations(exp, ref: dict, s: dict) -> dict:
    """Deviation of one run's series `s` (energy_series) from the reference
    (sph.cases.tgv3d_reference.deviations, with the profile's early window and u_ref)."""
    return ref_mod.deviations(ref, s, exp.analysis.early_window, exp.material.u_ref)


def read_trajectory(path, traj: str = "00000") -> dict:
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


def metrics(run, tr: dict) -> dict:
    """Metrics of one finished run, from its per-frame series and metadata.json."""
    exp, meta, attrs = run.settings, tr["metadata"], tr["attrs"]
    n_steps = int(attrs["n_steps"])
    row = {"case": run.case, "method": run.method, "n_side": run.n_side, "dx": run.dx, "dtype": run.numerics.dtype,
           "start": run.start, "n_particles": tr["n_particles"], "n_steps": n_steps,
           "dt": meta["dt"], "t_end": float(tr["time"][-1]), "write_every": meta["write_every"],
           "n_frames": int(tr["time"].shape[0]), **records.timing(attrs, n_steps),
           "n_reallocations": int(attrs["n_reallocations"])}
    row.update(deviations(exp, load_reference(exp), energy_series(exp, tr)))
    row["density_error_max"] = float(np.max(tr["density_error"]))
    return row


def record(run, row: dict) -> dict:
    return {"errors": {**{k: row[k] for k in ("e_kin_rms_dev", "e_kin_max_dev", "e_kin_rms_rel", "dissipation_rms_dev",
                                              "dissipation_max_dev", "dissipation_rms_rel")},
                       "peak_t": abs(row["peak_t_err"]), "peak_height": abs(row["peak_dissipation_relerr"]),
                       "early_rate": abs(row["early_rate_relerr"])},
            "n_side": run.n_side, "start": run.start}
