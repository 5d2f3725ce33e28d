"""Post-processing of the lid-driven cavity runs: centreline profiles of the stored frames,
deviations from Ghia et al. (1982), steadiness, and the metrics row of one run.

The Ghia tables, the wall-aware Shepard interpolation of the centreline profiles and the deviations
are sph.cases.ldc_reference's (a script uses them alike); this file reads a run's frames, averages
the profiles over the last `analysis.average_frames` frames (the acoustic noise of the weakly
compressible flow averages out) and collects the metrics. Deviations are taken at Ghia's 17 points
of each table (Re = `ghia_re`), walls included (u = 1 at the lid, 0 at the bottom; v = 0 at the side
walls), and over the 15 interior points.

Steadiness: `e_kin_change` compares the mean E_kin over the last `analysis.steady_window` time units
with the mean over the window before (sph.cases.ldc_reference.window_change), `profile_change` the
profiles averaged over the last `average_frames` frames with those of the frames before. Until
2026-12 `e_kin_change` compared two single frames, E_kin(t_end) and E_kin(t_end - steady_window),
which the acoustic noise of the weakly compressible flow moves by percents (issue 22: a cavity run
read 4.5 % drift where its 5-unit means drift 0.7 %). On the smoke profile (t_end 4, window 1, frames every 0.2;
dx 0.05 / 0.04) the single frames read SPH 2.5 / 0.4 %, TVF 8.5 / 9.9 %, Riemann 15.0 / 7.8 %, the
window means 2.6 / 2.4 %, 6.8 / 8.9 %, 9.6 / 8.3 % (the flow is still spinning up at t = 4).

The harness's analysis module (lab.experiment): out of the runs' keys, so editing it (or the
`analysis` settings) re-evaluates the stored runs on the next make without re-running them.
"""
import dataclasses
import json
from pathlib import Path

import h5py
import numpy as np

from sph.cases import ldc_reference as ref
from lab import record as records
from lab.protocol import Table
from sph.kernels import make_kernel
from sph.precision import resolve
from sph.state import FLUID, MOVING_WALL, WALL

TABLE = Table(rows="metrics")


def read_trajectory(path) -> dict:
    """What `metrics` reads of a run's trajectory: its path (the Interpolator reads the frames it needs)."""
    return {"path": Path(path)}


def metrics(run, traj: dict) -> dict:
    """The metrics row of one finished run (`evaluate`)."""
    return evaluate(run.settings, run.method, run.dx, traj["path"].parent)[0]


def record(run, row: dict) -> dict:
    """Target: the first figure that shows the run (ldc2d when none does)."""
    return {"target": run.groups[0] if run.groups else "ldc2d",
            "errors": {"ghia_u_rms": row["u_rms"], "ghia_v_rms": row["v_rms"],
                       "ghia_rms": float(np.hypot(row["u_rms"], row["v_rms"]) / np.sqrt(2))}}


class Interpolator:
    """Centreline interpolation of one run's frames (reads traj.h5 and metadata.json)."""

    def __init__(self, folder, analysis):
        folder = Path(folder)
        self.meta = json.loads((folder / "metadata.json").read_text())
        self.analysis = analysis
        num = self.meta["numerics"]
        resolve(num["dtype"])  # the run's precision (x64 on for a float64 run), whatever ran before in the process
        dx = float(self.meta["dx"])
        self.kernel = make_kernel(num["kernel"], num["h_factor"] * dx, int(self.meta["dim"]))
        self.offset = float(self.meta["cavity_offset"])
        self.path = folder / "traj.h5"
        with h5py.File(self.path, "r") as f:
            g = f["00000"]
            self.tag = g["particle_type"][...]
            self.time = g["time"][...]
            self.e_kin = g["e_kin"][...]
            self.mass = g["checkpoint/mass"][...] if "checkpoint/mass" in g else None
            self.n_frames = g["position"].shape[0]
        if self.mass is None:
            rho_ref = float(self.meta["material"]["rho_ref"])
            self.mass = np.full(self.tag.shape, rho_ref * dx ** int(self.meta["dim"]))
        self.fluid = self.tag == FLUID
        lid = float(self.meta["lid_velocity"])
        self.u_wall = np.zeros((len(self.tag), int(self.meta["dim"])))
        self.u_wall[self.tag == MOVING_WALL, 0] = lid
        assert np.all(np.isin(self.tag, (FLUID, WALL, MOVING_WALL)))
        self._sources = {}

    def frame(self, k: int):
        """(r, velocity, rho) of frame k (velocity per analysis.velocity)."""
        name = "velocity" if self.analysis.velocity == "transport" else "momentum_velocity"
        with h5py.File(self.path, "r") as f:
            g = f["00000"]
            return g["position"][k], g[name][k], g["density"][k]

    def sources(self, k: int):
        """(r, velocity, volume) of the particles the profiles of frame k interpolate from: the fluid,
        and with `walls: mirror` also the walls carrying their no-slip velocity. Cached per frame
        (the Ghia points and the plotted lines read the same frames)."""
        if k not in self._sources:
            r, vel, rho = self.frame(k)
            self._sources[k] = ref.sources(r, vel, self.mass / rho, self.fluid, self.u_wall, self.kernel,
                                           self.analysis.walls)
        return self._sources[k]

    def profiles(self, k: int, coord_u, coord_v):
        """u at (0.5, coord_u) and v at (coord_v, 0.5), cavity coordinates, from frame k."""
        return ref.profiles(self.sources(k), coord_u, coord_v, self.offset, self.kernel)

    def averaged(self, frames, coord_u, coord_v):
        """Mean and standard deviation over `frames` of the two profiles."""
        us, vs = zip(*(self.profiles(k, coord_u, coord_v) for k in frames))
        us, vs = np.array(us), np.array(vs)
        return us.mean(0), us.std(0), vs.mean(0), vs.std(0)


# -- evaluation of one run -------------------------------------------------------------------------
def evaluate(exp, method: str, dx: float, folder) -> tuple[dict, dict]:
    """The metrics row of one finished run in `folder` (steadiness: window means, module docstring) and its
    profiles (y, u, u_std along x = 0.5; x, v, v_std along y = 0.5; at Ghia's points; t_from, t_to)."""
    folder = Path(folder)
    ip = Interpolator(folder, exp.analysis)
    an = exp.analysis
    yg, ug = ref.ghia("u", exp.ghia_re)
    xg, vg = ref.ghia("v", exp.ghia_re)
    line = np.linspace(0.0, 1.0, an.n_points)
    nf = min(an.average_frames, ip.n_frames)
    last = list(range(ip.n_frames - nf, ip.n_frames))
    u_g, u_g_std, v_g, v_g_std = ip.averaged(last, yg, xg)
    u_l, u_l_std, v_l, v_l_std = ip.averaged(last, line, line)
    prev = list(range(max(0, ip.n_frames - 2 * nf), ip.n_frames - nf))
    if prev:
        pu, _, pv, _ = ip.averaged(prev, yg, xg)
        change = float(np.sqrt(np.mean(np.concatenate([(u_g - pu) ** 2, (v_g - pv) ** 2]))))
    else:
        change = np.nan
    t = ip.time
    lines = dict(y=line, u=u_l, u_std=u_l_std, x=line, v=v_l, v_std=v_l_std, ghia_y=yg, ghia_u=ug, sim_u=u_g,
                 sim_u_std=u_g_std, ghia_x=xg, ghia_v=vg, sim_v=v_g, sim_v_std=v_g_std, t_from=t[last[0]],
                 t_to=t[last[-1]])

    # the same deviations with the other wall treatment of the interpolation, for comparison
    other = "fluid" if an.walls == "mirror" else "mirror"
    ip_o = Interpolator(folder, dataclasses.replace(an, walls=other))
    uo, _, vo, _ = ip_o.averaged(last, yg, xg)
    with h5py.File(folder / "traj.h5", "r") as f:
        g = f["00000"]
        attrs = dict(g.attrs)
        rho_err = float(np.max(g["density_error"][...]))
        r_end = g["position"][-1][ip.fluid] - ip.offset
    # fluid particles that ended up inside a wall (more than half a spacing beyond the cavity)
    outside = int(np.sum(np.any((r_end < -0.5 * dx) | (r_end > 1.0 + 0.5 * dx), axis=1)))
    meta = ip.meta
    n_steps = int(attrs.get("n_steps", 0))
    i_min = int(np.argmin(u_l))
    row = {"case": exp.case, "method": method, "dx": dx, "dtype": meta["dtype"],
           "n_particles": int(len(ip.tag)), "n_fluid": int(ip.fluid.sum()), "n_steps": n_steps, "dt": meta["dt"],
           "t_end": float(t[-1]), "n_frames": ip.n_frames, "avg_t_from": float(t[last[0]]),
           "avg_t_to": float(t[last[-1]]), "interpolation": f"{an.walls}/{an.velocity}",
           **ref.deviations(u_g, v_g, exp.ghia_re),
           f"u_rms_{other}": float(np.sqrt(np.mean((uo - ug) ** 2))), f"u_maxdev_{other}": float(np.max(np.abs(uo - ug))),
           f"v_rms_{other}": float(np.sqrt(np.mean((vo - vg) ** 2))), f"v_maxdev_{other}": float(np.max(np.abs(vo - vg))),
           "u_min": float(u_l[i_min]), "y_u_min": float(line[i_min]),
           "v_max": float(np.max(v_l)), "v_min": float(np.min(v_l)),
           "profile_change": change, "e_kin_change": ref.window_change(t, ip.e_kin, an.steady_window),
           "e_kin_end": float(ip.e_kin[-1]), "density_error_max": rho_err, "fluid_outside": outside,
           **records.timing(attrs, n_steps), "n_reallocations": int(attrs.get("n_reallocations", 0))}
    return row, lines
