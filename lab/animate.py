"""A short animated GIF of one run: the particles of a trajectory file, coloured by a field.

`render("traj.h5", "run.gif")` reads a trajectory (lab.io's layout) and draws, for a bounded number
of frames sampled evenly from the stored ones (first and last included), the fluid particles as
dots coloured by a field (`speed` = |v| by default; `pressure`, `density` or `temperature` where the
run stored them), the wall particles in grey (moving walls darker), on axes fixed to the run's
domain (`bounds` of the metadata.json beside the file, else the particles' extent), with the
simulated time, a colour bar with one range for the whole animation, and the case, method and dx
as title. Written with matplotlib's PillowWriter (pillow only; ffmpeg is not needed), small figure
and dpi, particles beyond `max_particles` subsampled: a few MB at most, to look at a run at a glance
(ParaView on traj.xdmf for anything more).

A 3D trajectory is drawn as its mid-plane slice: the particles in a slab one dx thick at the middle
of the domain in z, projected on x-y (ParaView on traj.xdmf for the whole volume).
Only reads finished files, so it cannot change a run's numbers (lab.keys.NUMBER_NEUTRAL).

    python -m lab.animate results/paper/tgv2d/tvf_dx0.01/traj.h5 tgv.gif [--field pressure] [--frames 60]
"""
import argparse
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
from matplotlib.animation import PillowWriter
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image

from . import io
from sph.errors import ConfigError
from sph.state import FLUID, MOVING_WALL

FIELDS = {
    "speed": (("velocity", "momentum_velocity"), "|v|"),
    "pressure": (("pressure",), "p"),
    "density": (("density",), r"$\rho$"),
    "temperature": (("temperature",), "T"),
}
"""Colour fields: name -> (trajectory datasets it can be computed from, first found wins; label)."""

DEFAULT_FRAMES = 60
MAX_PARTICLES = 40_000


@dataclass(frozen=True)
class Animation:
    """What `render` wrote: the GIF, its number of frames, their size in pixels, the colour range."""
    path: Path
    n_frames: int
    size: tuple
    vmin: float
    vmax: float


def available_fields(traj: dict) -> list:
    """The FIELDS names that trajectory `traj` (io.read_trajectory) can be coloured by."""
    return [name for name, (sources, _) in FIELDS.items() if any(s in traj for s in sources)]


def field_values(traj: dict, field: str, path="trajectory") -> np.ndarray:
    """(T, N) values of colour field `field`; a ConfigError naming the field and the available ones
    when it is unknown or was not stored."""
    if field not in FIELDS:
        raise ConfigError(f"{path}: field {field!r} is not one of {list(FIELDS)}; "
                          f"this trajectory has {available_fields(traj)}")
    sources, _ = FIELDS[field]
    for s in sources:
        if s in traj:
            a = np.asarray(traj[s], dtype=np.float64)
            return np.linalg.norm(a, axis=-1) if a.ndim == 3 else a
    raise ConfigError(f"{path}: field {field!r} was not stored in this run (it keeps "
                      f"{[k for k in io.FIELDS if k in traj]}); available: {available_fields(traj)}")


def frame_indices(n_stored: int, frames: int) -> np.ndarray:
    """At most `frames` frame indices spread evenly over `n_stored`, first and last included."""
    if frames < 1:
        raise ConfigError(f"frames = {frames}: need at least 1")
    return np.unique(np.round(np.linspace(0, n_stored - 1, min(frames, n_stored))).astype(int))


def _limits(bounds, pos, margin):
    """Axis limits per dimension: the domain bounds, or the extent of the particles, plus `margin`."""
    if bounds is not None:
        lo, hi = np.asarray(bounds, float).T
    else:
        lo, hi = pos.min(axis=(0, 1)), pos.max(axis=(0, 1))
    return lo - margin, hi + margin


def _figure_size(width: float, height: float) -> tuple:
    """Figure size in inches for axes of data size width x height, plus room for title, labels and
    colour bar; rounded to quarter inches so that inches x dpi is a whole number of pixels."""
    aspect = height / width
    ax_w = min(6.4, 3.6 / aspect) if aspect < 1 else 3.6 / aspect
    ax_h = ax_w * aspect
    q = lambda x: round(4 * x) / 4  # noqa: E731
    return q(ax_w + 1.5), q(ax_h + 1.0)


class _GifWriter(PillowWriter):
    """PillowWriter whose frames share one palette (taken from the first, middle and last frame)
    and are not dithered: dithering speckles every frame anew, which GIF's compression pays for
    (files about a third smaller)."""

    def finish(self):
        frames = [f.convert("RGB") for f in self._frames]
        w, h = frames[0].size
        picks = sorted({0, len(frames) // 2, len(frames) - 1})
        sample = Image.new("RGB", (w, h * len(picks)))
        for i, k in enumerate(picks):
            sample.paste(frames[k], (0, h * i))
        palette = sample.quantize(colors=255, method=Image.Quantize.MEDIANCUT)
        frames = [f.quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
        frames[0].save(self.outfile, save_all=True, append_images=frames[1:], duration=int(1000 / self.fps),
                       loop=0)


def render(traj_path, out_path, field: str = "speed", frames: int = DEFAULT_FRAMES, fps: int = 10,
           dpi: int = 80, vmin: Optional[float] = None, vmax: Optional[float] = None,
           title: Optional[str] = None, max_particles: int = MAX_PARTICLES, traj: str = "00000") -> Animation:
    """Write an animated GIF of trajectory `traj` of `traj_path` to `out_path` (see the module
    docstring). Colour range: `vmin`/`vmax`, else [0, max] for speed and the 1st-99th percentile of
    the shown frames' fluid values for the other fields (a pressure spike would wash out the rest)."""
    traj_path, out_path = Path(traj_path), Path(out_path)
    tr, pos = _read_positions(traj_path, traj)
    values = field_values(tr, field, traj_path)
    idx = frame_indices(pos.shape[0], frames)
    times = tr["time"] if "time" in tr else np.arange(pos.shape[0], dtype=float)
    meta = _metadata(traj_path.parent)
    ptype = np.asarray(tr["particle_type"])
    view = _view(pos, ptype, idx, meta, max_particles)
    vmin, vmax = _colour_range(np.concatenate([values[k, f] for k, (f, _) in view.shown.items()]), field,
                               vmin, vmax)
    if title is None:
        title = (f"{meta.get('case', traj_path.parent.name)}, {meta.get('solver', '')}, dx = {view.dx:g}"
                 if meta else traj_path.parent.name)
    if view.z_mid is not None:
        title += f", slice z = {view.z_mid:.3g}"
    fig_w, fig_h = _figure_size(view.hi[0] - view.lo[0], view.hi[1] - view.lo[1])
    fig, wall_sc, sc, label = _figure(view, (fig_w, fig_h), dpi, (vmin, vmax), FIELDS[field][1], title,
                                      f"t = {times[idx[0]]:.2f}")

    out_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = out_path.with_name(out_path.stem + ".tmp" + out_path.suffix)
    writer = _GifWriter(fps=fps)
    with writer.saving(fig, str(tmp), dpi):
        for k, (f, w) in view.shown.items():
            wall_sc.set_offsets(pos[k, w, :2])
            wall_sc.set_array(np.where(ptype[w] == MOVING_WALL, 0.35, 0.65))  # grey, moving walls darker
            sc.set_offsets(pos[k, f, :2])
            sc.set_array(values[k, f])
            label.set_text(f"t = {times[k]:.2f}")
            writer.grab_frame()
    tmp.replace(out_path)
    return Animation(out_path, len(idx), (int(round(fig_w * dpi)), int(round(fig_h * dpi))), vmin, vmax)


def _read_positions(traj_path: Path, traj: str):
    """(trajectory, its (T, N, dim) positions); a ConfigError unless 2D or 3D with at least one frame."""
    tr = io.read_trajectory(traj_path, traj)
    pos = tr["position"]
    dim = pos.shape[-1]
    if dim not in (2, 3):
        raise ConfigError(f"{traj_path}: dim = {dim}; lab.animate draws 2D runs and mid-plane slices of 3D ones")
    if pos.shape[0] == 0:
        raise ConfigError(f"{traj_path}: the trajectory has no frames")
    return tr, pos


def _metadata(folder: Path) -> dict:
    """The run's metadata.json in `folder`; {} where there is none or it is not JSON."""
    if (folder / "metadata.json").exists():
        try:
            return json.loads((folder / "metadata.json").read_text())
        except ValueError:
            return {}
    return {}


@dataclass(frozen=True)
class _View:
    """What the animation shows: particle spacing dx, axis limits lo / hi, the 3D slice's height z_mid
    (None in 2D), the fluid subsampling stride, and per drawn frame k (fluid ids, wall ids)."""
    dx: float
    lo: np.ndarray
    hi: np.ndarray
    z_mid: Optional[float]
    stride: int
    shown: dict


def _view(pos, ptype, idx, meta: dict, max_particles: int) -> _View:
    """The particles of frames `idx` to draw: fluid subsampled to about `max_particles`, in 3D only
    those in the mid-plane slab; the axes the domain's `bounds` (else the particles' extent)."""
    dim = pos.shape[-1]
    fluid = np.flatnonzero(ptype == FLUID)
    dx = meta.get("dx")
    if dx is None:  # spacing from the fluid's area (volume) at the first frame
        span = np.ptp(pos[0, fluid], axis=0) if fluid.size > 1 else np.ones(dim)
        dx = float((max(np.prod(span), 1e-12) / max(fluid.size, 1)) ** (1.0 / dim))
    lo, hi = _limits(meta.get("bounds"), pos[idx], 0.5 * dx)
    z_mid = 0.5 * (lo[2] + hi[2]) if dim == 3 else None

    def in_plane(k, ids):
        """The particles `ids` of frame k that are drawn: all in 2D; in 3D a slab one dx thick at
        z_mid, off-centre by dx/4 so that it holds exactly one layer of a lattice either way."""
        return ids if dim == 2 else ids[np.abs(pos[k, ids, 2] - z_mid - 0.25 * dx) < 0.5 * dx]

    stride = max(1, -(-in_plane(0, fluid).size // max_particles))
    fluid = fluid[::stride]
    walls = np.flatnonzero(ptype != FLUID)
    return _View(dx, lo, hi, z_mid, stride, {k: (in_plane(k, fluid), in_plane(k, walls)) for k in idx})


def _colour_range(drawn: np.ndarray, field: str, vmin, vmax) -> tuple:
    """(vmin, vmax): the given ones, else [0, max] for speed and the 1st-99th percentile of the drawn
    values otherwise; widened around its value when empty."""
    if drawn.size == 0:
        drawn = np.zeros(1)
    if vmin is None:
        vmin = 0.0 if field == "speed" else float(np.nanpercentile(drawn, 1))
    if vmax is None:
        vmax = float(np.nanmax(drawn)) if field == "speed" else float(np.nanpercentile(drawn, 99))
    if not vmax > vmin:
        vmin, vmax = vmin - 0.5 * abs(vmin) - 1e-12, vmax + 0.5 * abs(vmax) + 1e-12
    return vmin, vmax


def _figure(view: _View, figsize, dpi, vrange, cbar_label, title, time_label):
    """(figure, wall scatter, fluid scatter, time label), laid out once (with the first frame's
    `time_label`) and frozen, markers sized to the spacing: walls squares of side dx, fluid discs of
    diameter 1.25 dx (times the subsampling)."""
    lo, hi = view.lo, view.hi
    vmin, vmax = vrange
    fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")  # no pyplot: the caller's
    FigureCanvasAgg(fig)                                           # backend stays as it is
    ax = fig.subplots()
    ax.set(xlim=(lo[0], hi[0]), ylim=(lo[1], hi[1]), aspect="equal")
    ax.tick_params(labelsize=7)
    # unsmoothed markers: fewer distinct colours, so GIF frames compress 2-3 times better
    wall_sc = ax.scatter([], [], c=[], cmap="gray", vmin=0.0, vmax=1.0, marker="s", linewidths=0,
                         antialiased=False)
    sc = ax.scatter([], [], c=[], cmap="viridis", vmin=vmin, vmax=vmax, marker="o", linewidths=0,
                    antialiased=False)
    cb = fig.colorbar(sc, ax=ax, shrink=0.9)
    cb.set_label(cbar_label, fontsize=8)
    cb.ax.tick_params(labelsize=7)
    fig.suptitle(title, fontsize=9)
    label = ax.set_title(time_label, fontsize=8)
    fig.canvas.draw()  # lay out once, then freeze: every frame has the same axes
    fig.set_layout_engine("none")
    pt_per_unit = ax.get_window_extent().width * 72.0 / dpi / (hi[0] - lo[0])
    size = max(0.3, (view.dx * pt_per_unit) ** 2)
    wall_sc.set_sizes([size])
    sc.set_sizes([1.25 ** 2 * size * view.stride])
    return fig, wall_sc, sc, label


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("traj", help="trajectory file (traj.h5)")
    ap.add_argument("out", help="GIF to write")
    ap.add_argument("--field", default="speed", help=f"colour field, one of {list(FIELDS)} (default speed)")
    ap.add_argument("--frames", type=int, default=DEFAULT_FRAMES, help="at most this many frames (default %(default)s)")
    ap.add_argument("--fps", type=int, default=10)
    ap.add_argument("--dpi", type=int, default=80)
    ap.add_argument("--range", type=float, nargs=2, metavar=("VMIN", "VMAX"), default=(None, None),
                    help="colour range (default: [0, max] for speed, 1st-99th percentile otherwise)")
    ap.add_argument("--title", default=None, help="default: case, method and dx from metadata.json")
    args = ap.parse_args(argv)
    if not Path(args.traj).is_file():
        raise ConfigError(f"{args.traj}: no such trajectory file")
    a = render(args.traj, args.out, field=args.field, frames=args.frames, fps=args.fps, dpi=args.dpi,
               vmin=args.range[0], vmax=args.range[1], title=args.title)
    print(f"{a.path}: {a.n_frames} frames, {a.size[0]}x{a.size[1]} px, "
          f"{a.path.stat().st_size / 1e6:.2f} MB, {args.field} in [{a.vmin:.3g}, {a.vmax:.3g}]")


if __name__ == "__main__":
    from .cli import script_main

    script_main(main)
