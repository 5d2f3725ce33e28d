"""What the force pass returns: the time derivatives its terms add up (per row of a block)."""
from dataclasses import dataclass
from typing import Optional

import jax

from .pvec import PVec


@jax.tree_util.register_dataclass
@dataclass(frozen=True)
class Rates:
    """Time derivatives of particle i (None: no term of the pass contributes to it).

    dudt   PVec of (B, 1): acceleration of the momentum velocity u
    dvdt   PVec of (B, 1): background-pressure acceleration of the transport velocity (TVF)
    dTdt   (B, 1): temperature rate
    """

    dudt: Optional[PVec] = None
    dvdt: Optional[PVec] = None
    dTdt: Optional[jax.Array] = None

    def __add__(self, other: "Rates") -> "Rates":
        def add(a, b):
            return b if a is None else a if b is None else a + b
        return Rates(add(self.dudt, other.dudt), add(self.dvdt, other.dvdt), add(self.dTdt, other.dTdt))
