"""The core's errors: configuration errors and value checks (no YAML, no files), and the run-time
errors of a simulation.

`ConfigError` names the bad key; `require` / `require_finite` are what config dataclasses call in
`__post_init__`. The harness (`lab.configtools`: YAML profiles) builds on these; the core never
imports the harness. `SimulationError` and its kinds (`BlowUp`, `ParticleEscaped`,
`NeighborOverflow`) stop a run whose state became unphysical (raised by `sph.guard.StepGuard`, the
rollouts and the driver).
"""
import dataclasses
import math


class ConfigError(ValueError):
    """A configuration value is unknown, mistyped or inconsistent; the message names the key.

    Errors raised while loading a profile of a YAML file (`load_profile`) also carry `file` (the
    YAML file), `profile` (the profile that was asked for), `origin` (the profile the offending key
    is written in: an inherited profile, or "command line" for an override) and `key` (its path);
    elsewhere these are None.
    """

    def __init__(self, msg: str, *, file=None, profile=None, origin=None, key=None):
        super().__init__(msg)
        self.file, self.profile, self.origin, self.key = file, profile, origin, key


def require(cond: bool, key: str, msg: str) -> None:
    if not cond:
        raise ConfigError(f"{key}: {msg}")


def is_finite_number(x) -> bool:
    """True for a real number (not a bool) that is neither NaN nor infinite."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def require_finite(obj, section: str = "", allow_inf=()) -> None:
    """Check that every number of the config dataclass `obj` is finite: its float and int fields
    and the entries of tuple fields (None is left to the class). Named `<section>.<field>`;
    fields in `allow_inf` may be +-inf (never NaN). For `__post_init__`, so that a config built in
    Python (not from YAML) is checked like one loaded by `from_mapping`."""
    prefix = f"{section}." if section else ""

    def check(v, key, name):
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return
        if math.isnan(v) or (math.isinf(v) and name not in allow_inf):
            raise ConfigError(f"{key}: must be a finite number, got {v!r}")

    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if isinstance(v, (tuple, list)):
            for i, x in enumerate(v):
                check(x, f"{prefix}{f.name}[{i}]", f.name)
        else:
            check(v, prefix + f.name, f.name)


class SimulationError(RuntimeError):
    """A run stopped because its state became unphysical. The message names the step, the particle
    and its position; `step` (the step that was refused), `particle` and `position` carry them, and
    `state` / `nbrs` the last good state (before that step) when known."""

    def __init__(self, msg: str, *, step=None, particle=None, position=None, state=None, nbrs=None):
        super().__init__(msg)
        self.step, self.particle, self.position = step, particle, position
        self.state, self.nbrs = state, nbrs


class BlowUp(SimulationError):
    """A field became NaN/inf, or a fluid speed exceeded the run's speed limit u_limit."""


class ParticleEscaped(SimulationError):
    """A fluid particle left the domain through a non-periodic side (beyond the wall layers or out of
    an open side of the box). Never taken: the neighbour search would wrap it around to the far side."""


class NeighborOverflow(SimulationError):
    """The neighbour list overflowed again and again although re-allocated (particles clumping)."""
