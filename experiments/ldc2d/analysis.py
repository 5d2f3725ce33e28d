"""Post-processing of the lid-driven cavity runs: Ghia et al. (1982) reference, centreline profiles
by SPH interpolation, deviations, steadiness, and metrics.csv.

Centreline profiles (cavity coordinates, [0, 1]^2): u(y) on x = 0.5 and v(x) on y = 0.5, by the
Shepard-normalised SPH interpolation

    f(x) = sum_j V_j f_j W(|x - x_j|, h) / sum_j V_j W(|x - x_j|, h),   V_j = m_j / rho_j,

over the fluid particles (analysis.walls = 'fluid'), optionally with the wall particles carrying the
generalized-wall no-slip velocity 2 u_wall - (Shepard average of the fluid velocity around them)
('mirror'; Adami 2012 eq. 23). The kernel and h are the run's. Profiles are averaged over the last
`analysis.average_frames` frames (acoustic noise of the weakly compressible flow averages out).

Deviations are taken at Ghia's 17 points of each table (Re = `ghia_re`), walls included (u = 1 at
the lid, 0 at the bottom; v = 0 at the side walls), and over the 15 interior points.

    python experiments/ldc2d/analysis.py --profile smoke [--results results/smoke]   (re-evaluate)
"""
import dataclasses
import json
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from sph.kernels import make_kernel
from sph.state import FLUID, MOVING_WALL, WALL
try:
    from . import settings as S
except ImportError:  # run as a script: its folder comes first on the import path (a copied folder works unchanged)
    import settings as S

REFS = S.ROOT / "validation_refs"
GHIA_FILES = {"u": "ldc_data_u_vel.csv", "v": "ldc_data_v_vel.csv"}


# -- Ghia et al. (1982) ------------------------------------------------------------------------------
def _number(s) -> float:
    """A table entry as float; tolerates a decimal comma ("0,00000"), blanks and quotes."""
    s = str(s).strip().strip('"').replace(" ", "")
    if "," in s and "." not in s:
        s = s.replace(",", ".")
    return float(s)


def ghia(component: str, re: int = 100, path=None):
    """(coordinate, velocity) of Ghia's Table I (component 'u': y, u(0.5, y)) or Table II ('v': x,
    v(x, 0.5)) at Reynolds number `re`, sorted by the coordinate. The csv has two header rows; the
    second names the columns ("pt. no.", "y"/"x", 100, 400, ..., "10,000")."""
    path = Path(path) if path is not None else REFS / GHIA_FILES[component]
    raw = pd.read_csv(path, header=None, dtype=str, keep_default_na=False)
    header = [h.strip().replace(",", "") for h in raw.iloc[1]]
    col = header.index(str(int(re)))
    body = raw.iloc[2:]
    body = body[body.iloc[:, 1].str.strip() != ""]
    coord = np.array([_number(s) for s in body.iloc[:, 1]])
    vel = np.array([_number(s) for s in body.iloc[:, col]])
    order = np.argsort(coord)
    return coord[order], vel[order]


# -- interpolation ---------------------------------------------------------------------------------
def shepard(points, r, f, volume, kernel):
    """Shepard-normalised SPH interpolation of `f` (N,) or (N, k) from particles at `r` (N, dim) with
    volumes `volume` (N,) onto `points` (P, dim); NaN where no particle is within the kernel support.
    Only the pairs within the kernel's cutoff are formed (a k-d tree), so the cost is O(P + N)."""
    points, f = np.asarray(points, np.float64), np.asarray(f, np.float64)
    pairs = cKDTree(points).sparse_distance_matrix(cKDTree(r), kernel.cutoff, output_type="ndarray")
    i, j = pairs["i"], pairs["j"]
    w = np.asarray(kernel.w(pairs["v"]), np.float64) * volume[j]
    tot = np.bincount(i, w, minlength=len(points))
    flat = f.reshape(len(f), -1)
    num = np.stack([np.bincount(i, w * flat[j, c], minlength=len(points)) for c in range(flat.shape[1])], axis=1)
    out = np.full(num.shape, np.nan)
    ok = tot > 0
    out[ok] = num[ok] / tot[ok, None]
    return out.reshape((len(points),) + f.shape[1:])


def mirrored_wall_velocity(r, vel, u_wall, fluid, volume, kernel):
    """No-slip velocity of the wall particles: 2 u_wall - Shepard average of the fluid velocity `vel`
    around each wall particle (wall particles without fluid neighbours keep u_wall)."""
    wall = ~fluid
    u_hat = shepard(r[wall], r[fluid], vel[fluid], volume[fluid], kernel)
    u_hat = np.where(np.isfinite(u_hat), u_hat, u_wall[wall])
    out = u_wall.copy()
    out[wall] = 2.0 * u_wall[wall] - u_hat
    return out


def centreline_points(coord, offset):
    """Scene positions of the vertical (x = 0.5, y = coord) and horizontal (x = coord, y = 0.5)
    centreline points."""
    coord = np.asarray(coord, np.float64)
    vert = np.stack([np.full_like(coord, 0.5), coord], axis=1) + offset
    horiz = np.stack([coord, np.full_like(coord, 0.5)], axis=1) + offset
    return vert, horiz


class Interpolator:
    """Centreline interpolation of one run's frames (reads traj.h5 and metadata.json)."""

    def __init__(self, folder, analysis: "S.Analysis"):
        folder = Path(folder)
        self.meta = json.loads((folder / "metadata.json").read_text())
        self.analysis = analysis
        num = self.meta["numerics"]
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
            vol = self.mass / rho
            if self.analysis.walls == "mirror":
                vel = np.where(self.fluid[:, None], vel,
                               mirrored_wall_velocity(r, vel, self.u_wall, self.fluid, vol, self.kernel))
                src = np.ones_like(self.fluid)
            else:
                src = self.fluid
            self._sources[k] = (r[src], vel[src], vol[src])
        return self._sources[k]

    def profiles(self, k: int, coord_u, coord_v):
        """u at (0.5, coord_u) and v at (coord_v, 0.5), cavity coordinates, from frame k."""
        r, vel, vol = self.sources(k)
        pu, _ = centreline_points(coord_u, self.offset)
        _, pv = centreline_points(coord_v, self.offset)
        u = shepard(pu, r, vel[:, 0], vol, self.kernel)
        v = shepard(pv, r, vel[:, 1], vol, self.kernel)
        return u, v

    def averaged(self, frames, coord_u, coord_v):
        """Mean and standard deviation over `frames` of the two profiles."""
        us, vs = zip(*(self.profiles(k, coord_u, coord_v) for k in frames))
        us, vs = np.array(us), np.array(vs)
        return us.mean(0), us.std(0), vs.mean(0), vs.std(0)


# -- evaluation of one run -------------------------------------------------------------------------
def evaluate(exp: "S.Experiment", method: str, dx: float, results) -> dict:
    """Profiles (saved to profiles.npz) and the metrics of one finished run."""
    folder = S.run_dir(results, method, dx)
    ip = Interpolator(folder, exp.analysis)
    an = exp.analysis
    yg, ug = ghia("u", exp.ghia_re)
    xg, vg = ghia("v", exp.ghia_re)
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
    np.savez(S.profiles_path(results, method, dx), y=line, u=u_l, u_std=u_l_std, x=line, v=v_l, v_std=v_l_std,
             ghia_y=yg, ghia_u=ug, sim_u=u_g, sim_u_std=u_g_std, ghia_x=xg, ghia_v=vg, sim_v=v_g, sim_v_std=v_g_std,
             t_from=t[last[0]], t_to=t[last[-1]])

    du, dv = u_g - ug, v_g - vg
    # the same deviations with the other wall treatment of the interpolation, for comparison
    other = next(w for w in S.WALL_MODES if w != an.walls)
    ip_o = Interpolator(folder, dataclasses.replace(an, walls=other))
    uo, _, vo, _ = ip_o.averaged(last, yg, xg)
    wall_u = (yg <= 0.0) | (yg >= 1.0)
    wall_v = (xg <= 0.0) | (xg >= 1.0)
    with h5py.File(folder / "traj.h5", "r") as f:
        g = f["00000"]
        attrs = dict(g.attrs)
        rho_err = float(np.max(g["density_error"][...]))
        r_end = g["position"][-1][ip.fluid] - ip.offset
    # fluid particles that ended up inside a wall (more than half a spacing beyond the cavity)
    outside = int(np.sum(np.any((r_end < -0.5 * dx) | (r_end > 1.0 + 0.5 * dx), axis=1)))
    meta = ip.meta
    n_steps = int(attrs.get("n_steps", 0))
    wall_s = float(attrs.get("wall_s", np.nan))
    # steadiness: relative change of E_kin over the last steady_window time units
    t0 = t[-1] - an.steady_window
    e_then = np.interp(t0, t, ip.e_kin) if t0 >= t[0] else np.nan
    i_min = int(np.argmin(u_l))
    row = {"case": exp.case, "method": method, "dx": dx, "dtype": meta["dtype"],
           "n_particles": int(len(ip.tag)), "n_fluid": int(ip.fluid.sum()), "n_steps": n_steps, "dt": meta["dt"],
           "t_end": float(t[-1]), "n_frames": ip.n_frames, "avg_t_from": float(t[last[0]]),
           "avg_t_to": float(t[last[-1]]), "interpolation": f"{an.walls}/{an.velocity}",
           "u_rms": float(np.sqrt(np.mean(du**2))), "u_maxdev": float(np.max(np.abs(du))),
           "v_rms": float(np.sqrt(np.mean(dv**2))), "v_maxdev": float(np.max(np.abs(dv))),
           "u_rms_interior": float(np.sqrt(np.mean(du[~wall_u] ** 2))),
           "v_rms_interior": float(np.sqrt(np.mean(dv[~wall_v] ** 2))),
           f"u_rms_{other}": float(np.sqrt(np.mean((uo - ug) ** 2))), f"u_maxdev_{other}": float(np.max(np.abs(uo - ug))),
           f"v_rms_{other}": float(np.sqrt(np.mean((vo - vg) ** 2))), f"v_maxdev_{other}": float(np.max(np.abs(vo - vg))),
           "u_min": float(u_l[i_min]), "y_u_min": float(line[i_min]),
           "v_max": float(np.max(v_l)), "v_min": float(np.min(v_l)),
           "profile_change": change, "e_kin_change": float(abs(ip.e_kin[-1] / e_then - 1.0)),
           "e_kin_end": float(ip.e_kin[-1]), "density_error_max": rho_err, "fluid_outside": outside,
           "wall_s": wall_s, "compile_s": float(attrs.get("compile_s", np.nan)),
           "ms_per_step": 1e3 * wall_s / n_steps if n_steps else np.nan,
           "n_reallocations": int(attrs.get("n_reallocations", 0))}
    return row


def main(args):
    exp = S.load(args.profile)
    results = args.results
    from sph.harness import io
    for dx in exp.dx:
        for m in exp.methods:
            st = io.trajectory_status(S.run_dir(results, m.name, dx) / "traj.h5")
            if st["complete"]:
                row = evaluate(exp, m.name, dx, results)
                print(f"{m.name} {S.dx_tag(dx)}: u_rms {row['u_rms']:.4f} v_rms {row['v_rms']:.4f} "
                      f"(interior {row['u_rms_interior']:.4f} / {row['v_rms_interior']:.4f})")
            else:
                print(f"{m.name} {S.dx_tag(dx)}: not finished ({st['n_frames']} frames)")


if __name__ == "__main__":
    from sph.harness.cli import profile_main

    profile_main(main, __doc__)
