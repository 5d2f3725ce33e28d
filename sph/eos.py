"""Equations of state p(rho) and their inverses rho(p); the pressure pass."""
from dataclasses import dataclass

from .passes import Pass


@dataclass(frozen=True)
class TaitEoS:
    """Tait equation of state (Monaghan 1994; Adami, Hu & Adams 2012, eq. 6).

    p = p_ref ((rho / rho_ref)^gamma - 1) + p_bg,  p_ref = rho_ref c_ref^2 / gamma.
    gamma = 1 gives the linear EoS used for the validation cases.
    """

    rho_ref: float
    c_ref: float
    gamma: float = 1.0
    p_bg: float = 0.0

    @property
    def p_ref(self) -> float:
        return self.rho_ref * self.c_ref**2 / self.gamma

    def p(self, rho):
        return self.p_ref * ((rho / self.rho_ref) ** self.gamma - 1.0) + self.p_bg

    def rho(self, p):
        return self.rho_ref * ((p - self.p_bg) / self.p_ref + 1.0) ** (1.0 / self.gamma)


@dataclass(frozen=True)
class RiemannEoS:
    """Linear (acoustic) EoS of Riemann SPH (Zhang, Hu & Adams 2017b, eq. 3).

    p = c_ref^2 (rho - rho_ref) + p_bg.
    """

    rho_ref: float
    c_ref: float
    p_bg: float = 0.0

    @property
    def p_ref(self) -> float:
        return self.rho_ref * self.c_ref**2

    def p(self, rho):
        return self.c_ref**2 * (rho - self.rho_ref) + self.p_bg

    def rho(self, p):
        return (p - self.p_bg) / self.c_ref**2 + self.rho_ref


@dataclass(frozen=True)
class PressurePass(Pass):
    """Step 3: p = EoS(rho) on every particle (walls take theirs from the wall pass after)."""

    eos: object
    reads = ("rho",)
    writes = ("p",)

    @classmethod
    def build(cls, scene, numerics, c):
        return cls(c.eos)

    def __call__(self, f, ctx, idx, step):
        return f.replace(p=self.eos.p(f.rho))
