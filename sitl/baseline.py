"""A scale from the test data alone: the error of particles frozen at the last input frame.

On the test windows every model is evaluated on (the first eval.n_trajs, round-robin over the seeds:
`common.n_windows`), a "model" that predicts no motion at all scores, at rollout step k, the mean
squared periodic displacement of the particles between the last input frame and frame k. MSE_5 and
MSE_20 are LagrangeBench's (the mean over the first 5 / 20 steps of the squared displacement,
averaged over particles and coordinates, `MetricsComputer.mse`); MSE_Ekin is the mean squared true
kinetic energy (the frozen particles have none). A model above these numbers does
worse than not moving: the study's table shows them as its scale (sitl/study.py).

    .venv-lb/bin/python -c "from sitl import baseline ..."   (used by sitl/study.py)
"""
import numpy as np

from sitl import common as C
from sitl import settings as S
from sitl import stats


def wrap(d: np.ndarray, box: np.ndarray) -> np.ndarray:
    """A displacement in the periodic box: each component in [-box / 2, box / 2]."""
    return d - box * np.round(d / box)


def eval_windows(exp: S.Experiment, path, n_windows: int = None):
    """(each test window's positions as float64 (particles, input + rollout frames, dim), the periodic
    box, the dataset's metadata): the profile's test windows in `path` (a generated dataset folder),
    the first `n_windows` of them (default: those the models are evaluated on, `common.n_windows`)."""
    _, _, data_test = C.datasets(exp, path)
    meta = data_test.metadata
    box = np.array([b[1] - b[0] for b in meta["bounds"]], dtype=np.float64)
    n = C.n_windows(exp, data_test) if n_windows is None else n_windows
    return [np.asarray(data_test[i][0], dtype=np.float64) for i in range(n)], box, meta


def _steps(exp: S.Experiment, windows: list, box: np.ndarray, moving: bool = False) -> np.ndarray:
    """(windows, rollout steps) MSE of particles frozen at the last input frame, or (`moving`) moving
    on with its last velocity: r^k = r^0 + k d(r^0, r^-1)."""
    isl, n = exp.model.input_seq_length, exp.eval.n_rollout_steps
    k = np.arange(1, n + 1)[None, :, None]
    out = []
    for pos in windows:
        v = wrap(pos[:, isl - 1:isl] - pos[:, isl - 2:isl - 1], box) if moving else 0.0
        out.append(np.mean(wrap(pos[:, isl:isl + n] - pos[:, isl - 1:isl] - k * v, box) ** 2, axis=(0, 2)))
    return np.array(out)  # per rollout step: mean over particles and coordinates


def _e_kin(exp: S.Experiment, windows: list, box: np.ndarray, meta: dict) -> list:
    """Per window, LagrangeBench's MSE_Ekin of particles frozen at the last input frame: their
    kinetic energy is zero, so it is the mean over the rollout's velocity frames of the true E_kin^2,
    E_kin = dx^dim sum over particles of |v|^2 with v the periodic displacement between consecutive
    rollout frames (every eval.metrics_stride-th) over the frame interval (`MetricsComputer.e_kin`).
    A model above it has more kinetic energy error than one that does not move at all."""
    isl, n, s = exp.model.input_seq_length, exp.eval.n_rollout_steps, exp.eval.metrics_stride
    frame_dt, vol = meta["dt"] * meta["write_every"], meta["dx"] ** meta["dim"]
    out = []
    for pos in windows:
        target = pos[:, isl:isl + n]                                   # (particles, n, dim)
        v = wrap(target[:, 1::s] - target[:, 0:-1:s], box) / frame_dt
        out.append(float(np.mean((vol * np.sum(v**2, axis=(0, 2))) ** 2)))
    return out


def frozen_steps(exp: S.Experiment, path, n_windows: int = None) -> np.ndarray:
    """(windows, rollout steps): the MSE at each step of particles frozen at the last input frame, on
    the profile's test windows in `path` (the first `n_windows`)."""
    windows, box, _ = eval_windows(exp, path, n_windows)
    return _steps(exp, windows, box)


def frozen(exp: S.Experiment, path, n_boot: int = 2000) -> dict:
    """{"mse5", "mse20", "e_kin", "ci_mse20", "n_windows", "per_window": {"mse5", "mse20", "e_kin"}} of
    particles frozen at the last input frame, on the profile's test windows in `path` (a generated
    dataset folder)."""
    windows, box, meta = eval_windows(exp, path)
    steps = _steps(exp, windows, box)
    per = {"mse5": [float(s[:5].mean()) for s in steps], "mse20": [float(s[:20].mean()) for s in steps],
           "e_kin": _e_kin(exp, windows, box, meta)}
    return {"mse5": float(np.mean(per["mse5"])), "mse20": float(np.mean(per["mse20"])),
            "e_kin": float(np.mean(per["e_kin"])), "ci_mse20": list(stats.bootstrap_ci(per["mse20"], n_boot)),
            "n_windows": len(per["mse20"]), "per_window": per}


def constant_velocity(exp: S.Experiment, path, n_boot: int = 2000) -> dict:
    """{"mse5", "mse20", "ci_mse20", "n_windows", "per_window"}: particles moving on with their last
    velocity (r^k = r^0 + k d(r^0, r^-1), no learning, no physics) on the same test windows: the
    floor of sense a model must beat to have learned any dynamics."""
    windows, box, _ = eval_windows(exp, path)
    steps = _steps(exp, windows, box, moving=True)
    per = {"mse5": [float(s[:5].mean()) for s in steps], "mse20": [float(s[:20].mean()) for s in steps]}
    return {"mse5": float(np.mean(per["mse5"])), "mse20": float(np.mean(per["mse20"])),
            "ci_mse20": list(stats.bootstrap_ci(per["mse20"], n_boot)), "n_windows": len(per["mse20"]),
            "per_window": per}
