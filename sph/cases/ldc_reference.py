"""The lid-driven cavity against Ghia, Ghia & Shin (1982): their tables (validation_refs/
ldc_data_{u,v}_vel.csv, read by path), the wall-aware centreline interpolation, the deviations, and
a steadiness check. Kept apart from sph.cases.ldc (the scene and its recipe) so that editing a
comparison re-runs nothing: a run's cache key covers the modules its scene imports.

Centreline profiles (cavity coordinates, [0, 1]^2): u(y) on x = 0.5 and v(x) on y = 0.5, by the
Shepard-normalised SPH interpolation

    f(x) = sum_j V_j f_j W(|x - x_j|, h) / sum_j V_j W(|x - x_j|, h),   V_j = m_j / rho_j,

over the fluid particles (walls = 'fluid'), or also over the wall particles carrying the
generalized-wall no-slip velocity 2 u_wall - (Shepard average of the fluid velocity around them)
(walls = 'mirror', the default; Adami 2012 eq. 23): 4 of Ghia's 34 points lie on walls, where the
velocity is the boundary condition that a fluid-only interpolation cannot reach.

    scene, numerics = ldc.setup(dx=0.02, re=400)
    ...                                                     # run, keep the last states
    out = ldc_reference.compare(solver, states, re=400)     # u_rms, v_rms, ... against Ghia
"""
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from ..errors import require
from ..state import FLUID
from . import ldc

REFS = Path(__file__).resolve().parents[2] / "validation_refs"
"""The reference data of the repository (read by path)."""
GHIA_FILES = {"u": "ldc_data_u_vel.csv", "v": "ldc_data_v_vel.csv"}
WALL_MODES = ("fluid", "mirror")
VELOCITIES = ("transport", "momentum")


# -- Ghia et al. (1982) ------------------------------------------------------------------------------
def _number(s) -> float:
    """A table entry as float; tolerates a decimal comma ("0,00000"), blanks and quotes."""
    s = str(s).strip().strip('"').replace(" ", "")
    if "," in s and "." not in s:
        s = s.replace(",", ".")
    return float(s)


def ghia(component: str, re: int = 100, path=None):
    """(coordinate, velocity) of Ghia's Table I (component 'u': y, u(0.5, y)) or Table II ('v': x,
    v(x, 0.5)) at Reynolds number `re` (one of sph.cases.ldc.GHIA_RE), sorted by the coordinate. The
    csv has two header rows; the second names the columns ("pt. no.", "y"/"x", 100, 400, ..., "10,000")."""
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


def deviations(u, v, re: int) -> dict:
    """RMS and largest |sim - Ghia| of the profiles u, v at Ghia's 17 points of each table (walls
    included: u = 1 at the lid, 0 at the bottom, v = 0 at the side walls), and the RMS over the 15
    interior points."""
    yg, ug = ghia("u", re)
    xg, vg = ghia("v", re)
    du, dv = np.asarray(u) - ug, np.asarray(v) - vg
    wall_u = (yg <= 0.0) | (yg >= 1.0)
    wall_v = (xg <= 0.0) | (xg >= 1.0)
    return {"u_rms": float(np.sqrt(np.mean(du**2))), "u_maxdev": float(np.max(np.abs(du))),
            "v_rms": float(np.sqrt(np.mean(dv**2))), "v_maxdev": float(np.max(np.abs(dv))),
            "u_rms_interior": float(np.sqrt(np.mean(du[~wall_u] ** 2))),
            "v_rms_interior": float(np.sqrt(np.mean(dv[~wall_v] ** 2)))}


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


def sources(r, vel, volume, fluid, u_wall, kernel, walls: str = "mirror"):
    """(r, velocity, volume) of the particles a profile interpolates from: the fluid, and with
    `walls='mirror'` also the walls carrying their no-slip velocity (`mirrored_wall_velocity`;
    u_wall: the walls' own velocity, the lid's on the moving wall)."""
    require(walls in WALL_MODES, "walls", f"{walls!r} is not one of {list(WALL_MODES)}")
    if walls == "mirror":
        vel = np.where(fluid[:, None], vel, mirrored_wall_velocity(r, vel, u_wall, fluid, volume, kernel))
        src = np.ones_like(fluid)
    else:
        src = fluid
    return r[src], vel[src], volume[src]


def profiles(src, coord_u, coord_v, offset: float, kernel):
    """u at (0.5, coord_u) and v at (coord_v, 0.5), cavity coordinates, from `sources`' particles."""
    r, vel, vol = src
    pu, _ = centreline_points(coord_u, offset)
    _, pv = centreline_points(coord_v, offset)
    return shepard(pu, r, vel[:, 0], vol, kernel), shepard(pv, r, vel[:, 1], vol, kernel)


def state_profiles(solver, state, coord_u, coord_v, walls: str = "mirror", velocity: str = "transport",
                   layers: int = 3):
    """u at (0.5, coord_u) and v at (coord_v, 0.5) of one ParticleState of the cavity `solver`
    (its scene, kernel and `layers` of wall particles); `velocity`: 'transport' (v, the particles'
    velocity) or 'momentum' (u)."""
    require(velocity in VELOCITIES, "velocity", f"{velocity!r} is not one of {list(VELOCITIES)}")
    sc = solver.scene
    fluid = np.asarray(sc.tag) == FLUID
    u_wall = np.where(fluid[:, None], 0.0, np.asarray(sc.u, np.float64))
    vel = np.asarray(state.v if velocity == "transport" else state.u, np.float64)
    r = np.asarray(state.r, np.float64)
    vol = np.asarray(state.mass, np.float64) / np.asarray(state.rho, np.float64)
    src = sources(r, vel, vol, fluid, u_wall, solver.kernel, walls)
    return profiles(src, coord_u, coord_v, ldc.offset(sc.dx, layers), solver.kernel)


def compare(solver, states, re: int, walls: str = "mirror", velocity: str = "transport", layers: int = 3) -> dict:
    """The centreline profiles at Ghia's points, averaged over `states` (one ParticleState or a list:
    the last frames of a run), and their `deviations` from Ghia's table at Reynolds number `re`;
    also the profiles themselves ('y', 'u', 'x', 'v')."""
    states = states if isinstance(states, (list, tuple)) else [states]
    y, x = ghia("u", re)[0], ghia("v", re)[0]
    us, vs = zip(*(state_profiles(solver, s, y, x, walls, velocity, layers) for s in states))
    u, v = np.mean(us, axis=0), np.mean(vs, axis=0)
    return {**deviations(u, v, re), "y": y, "u": u, "x": x, "v": v}


# -- steadiness ------------------------------------------------------------------------------------
def window_change(t, series, window: float) -> float:
    """|mean of `series` over the last `window` time units / mean over the window before - 1|: the
    last n frames against the n before them, n = round(window / frame spacing) (>= 1); NaN when the
    run holds fewer than 2n frames. Window means, not two single frames: the acoustic noise of the
    weakly compressible flow moves single frames of E_kin by percents."""
    t, f = np.asarray(t, float), np.asarray(series, float)
    spacing = (t[-1] - t[0]) / max(len(t) - 1, 1)
    n = max(1, int(round(window / spacing))) if spacing > 0 else 1
    if len(f) < 2 * n:
        return float("nan")
    return float(abs(np.mean(f[-n:]) / np.mean(f[-2 * n:-n]) - 1.0))
