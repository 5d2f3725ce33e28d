"""A study's methods: named solver variants (the effects their scenes declare) run at each resolution of
a profile, and the checks every such study's settings share (experiments/tgv2d, experiments/tgv3d).
Where a run writes and what the harness does with it is the protocol's (lab.experiment); what a
study measures stays with the study.
"""
from dataclasses import dataclass, field

from sph.config import Effects
from sph.errors import require

KEEPABLE = ("velocity", "momentum_velocity", "density", "pressure")
"""Per-frame fields a study may keep besides position (lab.io.FIELDS)."""


@dataclass(frozen=True)
class Method:
    """A named solver variant: the effects its scene declares."""

    name: str
    effects: Effects = field(default_factory=Effects)


def check_methods(methods) -> list:
    """The method names, each checked to be unique (at least one method)."""
    require(len(methods) > 0, "methods", "needs at least one method")
    names = [m.name for m in methods]
    for i, n in enumerate(names):
        require(names.index(n) == i, f"methods[{i}].name", f"{n!r} appears twice")
    return names


def check_output(exp) -> None:
    """The output settings every study has: `connectivity_radius_factor` and the kept fields."""
    require(exp.connectivity_radius_factor > 0, "connectivity_radius_factor",
            f"must be positive, got {exp.connectivity_radius_factor}")
    for i, k in enumerate(exp.keep):
        require(k in KEEPABLE, f"keep[{i}]", f"{k!r} is not one of {list(KEEPABLE)}")
