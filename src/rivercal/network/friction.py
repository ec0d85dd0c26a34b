"""Bed friction: the law (Strickler, Manning, Chezy) and its coefficient with a plausible range."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import NetworkModel, Real, num

__all__ = ["FRICTION_RANGES", "Friction"]

#: Plausible range of each friction coefficient; values outside are almost always a unit or type
#: mix-up (a Manning n given as a Strickler k_s, or the reverse).
FRICTION_RANGES: dict[str, tuple[float, float, str]] = {
    "strickler": (1.0, 200.0, "m^(1/3)/s"),
    "manning": (0.005, 1.0, "s/m^(1/3)"),
    "chezy": (1.0, 300.0, "m^(1/2)/s"),
}


class Friction(NetworkModel):
    """Bed friction law and coefficient.

    Attributes
    ----------
    type
        ``strickler`` (k_s in m^(1/3)/s, C = k_s R^(1/6), thesis Eq. 3-3), ``manning`` (n in
        s/m^(1/3), C = R^(1/6)/n) or ``chezy`` (C in m^(1/2)/s).
    value
        The coefficient, in the unit of its type; it must lie in the plausible range of
        :data:`FRICTION_RANGES` (this catches a Manning n given as a Strickler k_s).
    """

    type: Literal["strickler", "manning", "chezy"] = Field(
        default="strickler",
        description="friction law: 'strickler' (k_s, m^(1/3)/s), 'manning' (n, s/m^(1/3)) or 'chezy' (C, m^(1/2)/s)",
    )
    value: Real = Field(
        gt=0,
        description="friction coefficient in the unit of its type (Strickler k_s 1-200 m^(1/3)/s, "
        "Manning n 0.005-1 s/m^(1/3), Chezy C 1-300 m^(1/2)/s)",
    )

    @model_validator(mode="after")
    def _plausible(self) -> Friction:
        low, high, unit = FRICTION_RANGES[self.type]
        if not low <= self.value <= high:
            hint = ""
            if self.type == "strickler" and self.value < low:
                hint = '; is it a Manning n? then write type = "manning"'
            elif self.type == "manning" and self.value > high:
                hint = '; is it a Strickler k_s? then write type = "strickler"'
            raise FieldProblem(
                "value",
                f"{self.type} coefficient {num(self.value)} {unit} is outside the plausible range "
                f"{num(low)}-{num(high)} {unit}{hint}",
            )
        return self


