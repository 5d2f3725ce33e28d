"""XDMF sidecars: open a trajectory file (LagrangeBench layout, lab.io) directly in ParaView.

`write_sidecar("traj.h5")` writes ``traj.xdmf`` beside it: a temporal collection with one grid per
frame, the particles as a Polyvertex mesh whose geometry and attributes are hyperslabs of the HDF5
datasets (nothing is copied). In ParaView: File > Open > traj.xdmf ("Xdmf3 Reader T"), then e.g.
the Point Gaussian representation coloured by velocity.

    python -m lab.xdmf results/paper/tgv2d/tvf_dx0.01/traj.h5     # (re)write the sidecar by hand
"""
import sys
from pathlib import Path
from xml.sax.saxutils import quoteattr

import h5py

from .atomic import write_text

_VECTOR = ("velocity", "momentum_velocity")


def _slab(fname: str, path: str, t: int, shape: tuple, dtype: str, precision: int) -> str:
    rest = shape[1:]
    dims = " ".join(str(d) for d in rest)
    start = " ".join(["%d" % t] + ["0"] * len(rest))
    stride = " ".join(["1"] * len(shape))
    count = " ".join(["1"] + [str(d) for d in rest])
    return (f'<DataItem ItemType="HyperSlab" Dimensions="{dims}" Type="HyperSlab">'
            f'<DataItem Dimensions="3 {len(shape)}" Format="XML">{start} {stride} {count}</DataItem>'
            f'<DataItem Dimensions="{" ".join(str(d) for d in shape)}" NumberType="{dtype}" '
            f'Precision="{precision}" Format="HDF">{fname}:{path}</DataItem></DataItem>')


def sidecar_text(h5_path, traj: str = "00000") -> str:
    """The XDMF document for trajectory `traj` of `h5_path` (paths relative to the sidecar)."""
    h5_path = Path(h5_path)
    fname = h5_path.name
    with h5py.File(h5_path, "r") as f:
        g = f[traj]
        pos = g["position"]
        n_frames, n, dim = pos.shape
        pos_bytes = pos.dtype.itemsize
        times = g["time"][...] if "time" in g else range(n_frames)
        fields = {k: (g[k].shape, g[k].dtype) for k in g.keys()
                  if isinstance(g[k], h5py.Dataset) and k != "position" and g[k].ndim >= 2
                  and g[k].shape[0] == n_frames}
        has_type = "particle_type" in g
    prec = lambda dt: dt.itemsize  # noqa: E731
    out = ['<?xml version="1.0" ?>', '<Xdmf Version="3.0"><Domain>',
           '<Grid Name="particles" GridType="Collection" CollectionType="Temporal">']
    geom = "XYZ" if dim == 3 else "XY"
    for t in range(n_frames):
        out.append(f'<Grid Name="frame{t}" GridType="Uniform"><Time Value="{float(times[t])!r}"/>')
        out.append(f'<Topology TopologyType="Polyvertex" NumberOfElements="{n}"/>')
        out.append(f'<Geometry GeometryType="{geom}">'
                   + _slab(fname, f"/{traj}/position", t, (n_frames, n, dim), "Float", pos_bytes)
                   + "</Geometry>")
        if has_type:
            out.append('<Attribute Name="particle_type" AttributeType="Scalar" Center="Node">'
                       f'<DataItem Dimensions="{n}" NumberType="Int" Precision="4" Format="HDF">'
                       f'{fname}:/{traj}/particle_type</DataItem></Attribute>')
        for k, (shape, dtype) in sorted(fields.items()):
            kind = "Vector" if k in _VECTOR and len(shape) == 3 else "Scalar"
            out.append(f'<Attribute Name={quoteattr(k)} AttributeType="{kind}" Center="Node">'
                       + _slab(fname, f"/{traj}/{k}", t, shape, "Float", prec(dtype)) + "</Attribute>")
        out.append("</Grid>")
    out.append("</Grid></Domain></Xdmf>")
    return "\n".join(out) + "\n"


def write_sidecar(h5_path, traj: str = "00000") -> Path:
    """Write `<h5_path without .h5>.xdmf` beside the trajectory file; returns its path."""
    h5_path = Path(h5_path)
    out = h5_path.with_suffix(".xdmf")
    write_text(out, sidecar_text(h5_path, traj))
    return out


if __name__ == "__main__":
    for p in sys.argv[1:]:
        print(write_sidecar(p))
