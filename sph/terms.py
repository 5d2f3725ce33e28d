"""Which terms each pass of the step sums, chosen once from the scene's declared effects.

A term is a small frozen object `term(pairs, i, j)` (`sph.views`: particle i and its neighbours j
in a block). The density pass takes one term, the new density; the optional re-initialization pass
one; the wall pass one (the generalized wall condition); the force pass adds its terms' `Rates`
(du/dt, dv/dt, dT/dt) in order. An effect the scene does not declare has no term, so its physics is
never traced. A new effect is a term in its own module and one line in `choose_terms` (or, from
outside, `build_solver(..., extra_terms=(MyTerm(...),))`: force-pass terms added after these).
"""
from dataclasses import dataclass
from typing import Callable, Optional

from .config import Numerics
from .constants import Constants
from .density import Continuity, Reinitialize, Summation
from .forces import BodyForce
from .heat import Conduction
from .momentum import ArtificialViscosity, BackgroundPressure, Momentum
from .riemann import RiemannContinuity, RiemannMomentum
from .scene import Scene
from .walls import WallExtrapolation


@dataclass(frozen=True)
class Terms:
    """The terms of each pass (see the module docstring); `reinit_every` 0: no re-initialization."""

    density: Callable
    force: tuple
    wall: Optional[Callable] = None
    reinit: Optional[Callable] = None
    reinit_every: int = 0


def choose_terms(scene: Scene, numerics: Numerics, c: Constants, extra_terms=()) -> Terms:
    fx, mat, walls = scene.effects, scene.material, scene.effects.walls is not None
    if fx.riemann:
        density = RiemannContinuity(c.dt, c.c_ref, c.eos.rho, walls)
        force = [RiemannMomentum(mat.eta, c.c_ref, numerics.eta_limiter, c.eos.rho, walls)]
    else:
        density = Continuity(c.dt) if fx.density_evolution else Summation(c.w0)
        force = [Momentum(mat.eta, fx.tvf)]
    force += [BodyForce()] if c.force is not None else []
    force += [ArtificialViscosity(fx.artificial_viscosity, c.h, c.c_ref)] if fx.artificial_viscosity else []
    force += [BackgroundPressure(c.p_b)] if fx.tvf else []
    force += [Conduction(mat.kappa, mat.c_p)] if fx.heat else []
    return Terms(density=density, force=tuple(force) + tuple(extra_terms),
                 wall=WallExtrapolation(c.weight_floor, fx.heat) if walls else None,
                 reinit=Reinitialize(c.w0) if fx.density_reinit_every else None,
                 reinit_every=fx.density_reinit_every)
