"""lab.animate: a GIF of a tiny trajectory (a rotating patch of fluid in a walled box, written with
lab.io's writer, no solver) has the requested frames and size, its frames differ, and a field the
run did not store is refused with a message naming it and the available ones."""
import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

import sph
from lab import animate, io
from lab.configtools import ConfigError

N_FRAMES = 8
DX = 0.05


class _Frame:
    """The attributes TrajectoryWriter.append reads (lab.io.FIELDS), without building a solver."""

    def __init__(self, r, v, p):
        self.r, self.v, self.p = r, v, p
        self.rho = np.ones(len(r))


@pytest.fixture(scope="module")
def traj(tmp_path_factory):
    """A 20 x 20 fluid patch turning as a rigid vortex inside 2 layers of walls, the top ones a lid."""
    folder = tmp_path_factory.mktemp("anim")
    g = (np.arange(20) + 0.5) * DX + 2 * DX                      # fluid in [0.1, 1.1]^2
    fluid = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    w = (np.arange(24) + 0.5) * DX                                # box [0, 1.2]^2 with 2 wall layers
    grid = np.stack(np.meshgrid(w, w), -1).reshape(-1, 2)
    wall = grid[(np.minimum(grid, 1.2 - grid) < 2 * DX).any(axis=1)]
    r0 = np.concatenate([fluid, wall])
    lid = np.where(wall[:, 1] > 1.1, sph.MOVING_WALL, sph.WALL)
    ptype = np.r_[np.full(len(fluid), sph.FLUID), lid]
    c = np.array([0.6, 0.6])
    with io.TrajectoryWriter.create(folder / "traj.h5", ptype, dim=2, keep=("velocity", "density", "pressure")) as wr:
        for k in range(N_FRAMES):
            t = 0.1 * k
            a = 1.5 * t
            rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
            r = np.where(ptype[:, None] == sph.FLUID, (r0 - c) @ rot.T + c, r0)
            v = np.where(ptype[:, None] == sph.FLUID, 1.5 * np.stack([-(r - c)[:, 1], (r - c)[:, 0]], -1), 0.0)
            wr.append(_Frame(r, v, np.linalg.norm(r - c, axis=1) ** 2), step=k, t=t)
    (folder / "metadata.json").write_text(json.dumps({"case": "vortex", "solver": "none", "dx": DX,
                                                      "bounds": [[0.0, 1.2], [0.0, 1.2]]}))
    return folder / "traj.h5"


def _frames(path):
    with Image.open(path) as im:
        out = []
        for k in range(im.n_frames):
            im.seek(k)
            out.append(np.asarray(im.convert("RGB"), dtype=np.int16))
        return im.n_frames, im.size, out


def test_gif_has_the_frames_and_size_asked_for(traj, tmp_path):
    a = animate.render(traj, tmp_path / "v.gif", frames=5, dpi=60)
    n, size, frames = _frames(a.path)
    assert n == a.n_frames == 5
    assert size == a.size and 200 <= size[0] <= 500 and 200 <= size[1] <= 500
    assert a.path.stat().st_size < 2e6
    assert (a.vmin, round(a.vmax, 6)) == (0.0, round(1.5 * np.hypot(0.475, 0.475), 6))  # |v| = 1.5 |r - c|
    assert all(np.abs(f - frames[0]).sum() > 0 for f in frames[1:])  # the patch turns
    bigger = animate.render(traj, tmp_path / "w.gif", frames=20, dpi=120)
    assert bigger.n_frames == N_FRAMES  # never more than stored
    assert bigger.size == (2 * size[0], 2 * size[1])


def test_unknown_or_unstored_field_names_the_available_ones(traj, tmp_path):
    have = r"\['speed', 'pressure', 'density'\]"
    with pytest.raises(ConfigError, match=r"'temperature' was not stored .*available: " + have):
        animate.render(traj, tmp_path / "t.gif", field="temperature")
    with pytest.raises(ConfigError, match=r"'vorticity' is not one of .*this trajectory has " + have):
        animate.render(traj, tmp_path / "t.gif", field="vorticity")
    assert not (tmp_path / "t.gif").exists()


def test_command_line(traj, tmp_path):
    out = tmp_path / "p.gif"
    ok = subprocess.run([sys.executable, "-m", "lab.animate", str(traj), str(out), "--field", "pressure",
                         "--frames", "3"], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    assert _frames(out)[0] == 3
    bad = subprocess.run([sys.executable, "-m", "lab.animate", str(traj), str(out), "--field", "temperature"],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "'temperature'" in bad.stderr


def test_3d_run_is_drawn_as_its_mid_plane(tmp_path):
    """A 6^3 lattice moving in x with |v| = 1 + z: the slice holds one of its layers (z = 7/12, one of
    the two next to the middle), and the GIF shows it moving."""
    g = (np.arange(6) + 0.5) / 6
    r0 = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    with io.TrajectoryWriter.create(tmp_path / "traj.h5", np.zeros(len(r0)), dim=3, keep=("velocity",)) as wr:
        for k in range(4):
            r = r0 + [0.05 * k, 0.0, 0.0]
            wr.append(_Frame(r, np.tile([1.0, 0.0, 0.0], (len(r), 1)) * (1 + r[:, 2:]), None), step=k, t=0.1 * k)
    a = animate.render(tmp_path / "traj.h5", tmp_path / "s.gif")
    n, size, frames = _frames(a.path)
    assert n == 4 and size == a.size
    assert a.vmax == pytest.approx(1 + 7 / 12)
    assert np.abs(frames[-1] - frames[0]).sum() > 0
