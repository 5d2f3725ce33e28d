"""The ordered pass list of the step: one line per pass, in the order a step runs them.

Each entry is a pass class (`sph.passes.Pass`); `choose_passes` asks each for the pass of a scene
(`build` returns None where the scene does not declare its effect), so the step holds exactly the
declared physics. A new effect is a module with its pass and one line here.
"""
from . import density, eos, heat, surface_tension, terms, walls

PASSES = (
    density.DensityPass,                  # 2. rho^{n+1}: summation, continuity or Riemann
    density.ReinitPass,                   #    Shepard re-initialization every N steps
    eos.PressurePass,                     # 3. p = EoS(rho)
    walls.WallPass,                       # 4. generalized wall condition (Adami 2012)
    terms.ForcePass,                      # 5. du/dt, dv/dt, dT/dt: the force terms
    surface_tension.SurfaceTensionPass,   # 5. + continuum surface force (Morris 2000)
    heat.HeatPass,                        # 6. T^{n+1} (Cleary 1998)
)


def choose_passes(scene, numerics, c, extra_terms=()) -> tuple:
    """The passes of `scene`, in order; `extra_terms` are summed by the force pass after its own."""
    out = tuple(p for cls in PASSES if (p := cls.build(scene, numerics, c)) is not None)
    return tuple(p.adding(extra_terms) if isinstance(p, terms.ForcePass) else p for p in out) if extra_terms else out


def dt_limits(scene, numerics, h: float) -> dict:
    """The time-step limits the passes of `scene` add to sph.timestep's (e.g. the capillary limit)."""
    out = {}
    for cls in PASSES:
        out.update(cls.dt_limits(scene, numerics, h))
    return out
