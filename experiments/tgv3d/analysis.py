"""Post-processing of the 3D Taylor-Green runs: E_kin(t) and -dE/dt(t) from the written frames, and
their deviation from the JAX-Fluids reference (the metrics row of one run).

Kept apart from run.py on purpose: the run fingerprint covers settings.py, run.py and the sph
modules they and the solver import, not this file, so changing a metric re-evaluates the stored
trajectories without re-running them (the paper profile takes hours).

The normalisation of E_kin (per unit volume and density, the reference's) is
sph.cases.tgv3d.e_kin_normalised; -dE/dt by central differences over `analysis.dissipation_span`, the
reference and the deviations from it are sph.cases.tgv3d_reference's (which a script uses alike).
"""
import h5py
import numpy as np

from lab import io, record
from sph.cases import tgv3d
from sph.cases import tgv3d_reference as ref_mod

try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path
    import settings as S


def load_reference(exp: "S.Experiment") -> dict:
    """The JAX-Fluids reference of the profile (settings.reference_path), the exact t = 0 values in
    front (sph.cases.tgv3d_reference.load_reference)."""
    return ref_mod.load_reference(S.reference_path(exp), exp.nu, exp.material.u_ref)


def energy_series(exp: "S.Experiment", traj: dict) -> dict:
    """t, E_kin per unit volume (all frames); t_mid, -dE/dt (central differences over +-j frames,
    at the frames that have j neighbours on both sides); j (sph.cases.tgv3d_reference.energy_series)."""
    return ref_mod.energy_series(traj["time"], tgv3d.e_kin_normalised(traj["e_kin"], exp.material.rho_ref),
                                 exp.analysis.dissipation_span)


def deviations(exp: "S.Experiment", ref: dict, s: dict) -> dict:
    """Deviation of one run's series `s` (energy_series) from the reference
    (sph.cases.tgv3d_reference.deviations, with the profile's early window and u_ref)."""
    return ref_mod.deviations(ref, s, exp.analysis.early_window, exp.material.u_ref)


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
           "n_frames": int(tr["time"].shape[0]), **record.timing(attrs, n_steps),
           "n_reallocations": int(attrs["n_reallocations"])}
    row.update(deviations(exp, ref if ref is not None else load_reference(exp), energy_series(exp, tr)))
    row["density_error_max"] = float(np.max(tr["density_error"]))
    return row
