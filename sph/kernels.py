"""Smoothing kernels W(r, h) and their radial derivatives dW/dr.

Each kernel is a frozen dataclass with `h` (smoothing length), `dim`, `cutoff` (support radius) and
branch-free `w(r)` / `dwdr(r)` built from ramps max(0, a - q), so they are smooth enough for
`jax.grad` and vectorize over any array of distances.
"""
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np


def _ramp(x):
    return jnp.maximum(x, 0.0)


@dataclass(frozen=True)
class QuinticSpline:
    """Quintic spline of Morris, Fox & Zhu (1997), support 3h.

    W(q) = sigma [ (3-q)^5_+ - 6 (2-q)^5_+ + 15 (1-q)^5_+ ],  q = r / h,
    sigma = 1/(120 h), 7/(478 pi h^2), 1/(120 pi h^3) in 1D, 2D, 3D.
    """

    h: float
    dim: int
    support: float = 3.0

    @property
    def sigma(self) -> float:
        return {1: 1.0 / 120.0, 2: 7.0 / (478.0 * np.pi), 3: 1.0 / (120.0 * np.pi)}[self.dim] / self.h**self.dim

    @property
    def cutoff(self) -> float:
        return self.support * self.h

    def w(self, r):
        q = r / self.h
        return self.sigma * (_ramp(3.0 - q) ** 5 - 6.0 * _ramp(2.0 - q) ** 5 + 15.0 * _ramp(1.0 - q) ** 5)

    def dwdr(self, r):
        q = r / self.h
        return (self.sigma / self.h) * (
            -5.0 * _ramp(3.0 - q) ** 4 + 30.0 * _ramp(2.0 - q) ** 4 - 75.0 * _ramp(1.0 - q) ** 4
        )


@dataclass(frozen=True)
class WendlandC2:
    """Wendland C2 kernel (Wendland 1995; Dehnen & Aly 2012 normalization), support 2h, dim 2 or 3.

    W(q) = sigma (1 - q/2)^4_+ (2q + 1),  sigma = 7/(4 pi h^2) in 2D, 21/(16 pi h^3) in 3D.
    """

    h: float
    dim: int
    support: float = 2.0

    @property
    def sigma(self) -> float:
        return {2: 7.0 / (4.0 * np.pi), 3: 21.0 / (16.0 * np.pi)}[self.dim] / self.h**self.dim

    @property
    def cutoff(self) -> float:
        return self.support * self.h

    def w(self, r):
        q = r / self.h
        return self.sigma * _ramp(1.0 - 0.5 * q) ** 4 * (2.0 * q + 1.0)

    def dwdr(self, r):
        q = r / self.h
        # d/dq [(1-q/2)^4 (2q+1)] = -5 q (1-q/2)^3
        return (self.sigma / self.h) * (-5.0 * q * _ramp(1.0 - 0.5 * q) ** 3)


@dataclass(frozen=True)
class WendlandC4:
    """Wendland C4 kernel, support 2h, dim 2 or 3.

    W(q) = sigma (1 - q/2)^6_+ (35/12 q^2 + 3 q + 1),  sigma = 9/(4 pi h^2) in 2D, 495/(256 pi h^3) in 3D.
    """

    h: float
    dim: int
    support: float = 2.0

    @property
    def sigma(self) -> float:
        return {2: 9.0 / (4.0 * np.pi), 3: 495.0 / (256.0 * np.pi)}[self.dim] / self.h**self.dim

    @property
    def cutoff(self) -> float:
        return self.support * self.h

    def w(self, r):
        q = r / self.h
        return self.sigma * _ramp(1.0 - 0.5 * q) ** 6 * (35.0 / 12.0 * q**2 + 3.0 * q + 1.0)

    def dwdr(self, r):
        q = r / self.h
        # d/dq [(1-q/2)^6 (35/12 q^2 + 3q + 1)] = -(14/3) q (1 + 5q/2) (1-q/2)^5
        return (self.sigma / self.h) * (-(14.0 / 3.0) * q * (1.0 + 2.5 * q) * _ramp(1.0 - 0.5 * q) ** 5)


KERNELS = {"quintic": QuinticSpline, "wendland_c2": WendlandC2, "wendland_c4": WendlandC4}


def make_kernel(name: str, h: float, dim: int):
    """Kernel by config name; a wrong name or an unsupported dimension fails with a clear message."""
    if name not in KERNELS:
        raise ValueError(f"kernel: {name!r} is not one of {sorted(KERNELS)}")
    if name != "quintic" and dim not in (2, 3):
        raise ValueError(f"kernel: {name!r} is defined for dim 2 and 3, not dim={dim}")
    if dim not in (1, 2, 3):
        raise ValueError(f"dim: {dim} must be 1, 2 or 3")
    return KERNELS[name](h=h, dim=dim)
