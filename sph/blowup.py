"""A chunk of steps that went bad, located and explained: the first bad step by bisection from the
chunk's last good state, taken once more unguarded and diagnosed (`sph.guard.StepGuard.diagnose`,
naming the particle, its position and the likely cause), with where the last good frame is kept."""
from typing import Optional

from .errors import SimulationError
from .rollout import advance


def is_bad(d: dict, u_limit: Optional[float]) -> bool:
    return int(d["first_nonfinite"]) >= 0 or (u_limit is not None and float(d["u_max"]) > u_limit)


def with_checkpoint(err: SimulationError, solver, step: int, writer) -> SimulationError:
    """`err` with the note where the last good frame (`step`, the start of the chunk) is kept."""
    if writer is None:
        return err
    out = type(err)(f"{err}; the last good frame (step {step}, t={step * solver.dt:.6g}) is kept in the "
                    f"checkpoint of {writer.path}")
    out.__dict__.update(err.__dict__)
    return out


def locate_blowup(solver, chunk, diag_fn, state, nbrs, step, n, writer, error, u_limit) -> RuntimeError:
    """The chunk from the good `state` at `step` went bad within `n` steps: bisect for the first bad
    step, take it once more unguarded and name the first offending particle (`StepGuard.diagnose`)."""

    def advance_ok(m):
        try:
            s, nb, _ = advance(chunk, solver.neighbors, state, nbrs, step, m)
        except RuntimeError:
            return None
        return None if is_bad(diag_fn(s), u_limit) else (s, nb)

    lo, hi = 0, n  # after lo steps good, after hi steps not
    good = (state, nbrs)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        res = advance_ok(mid)
        if res is None:
            hi = mid
        else:
            lo, good = mid, res
    s_good, nb_good = good
    bad_step = step + lo + 1
    guard = solver.guard.with_limit(u_limit)
    err = guard.diagnose(s_good, nb_good, bad_step, why=str(error) if error is not None else "")
    err.__cause__ = error
    return with_checkpoint(err, solver, step, writer)
