"""Bed friction: the law and its coefficient with a plausible range, and the friction groups profiles refer to.

The laws: Strickler, Manning, Chézy and White-Colebrook.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import Identifier, NetworkModel, Real, num

__all__ = ["FRICTION_RANGES", "BranchFriction", "Friction", "FrictionGroup", "FrictionType"]

#: Plausible range of each friction coefficient; values outside are almost always a unit or type
#: mix-up (a Manning n given as a Strickler k_s, or the reverse).
FRICTION_RANGES: dict[str, tuple[float, float, str]] = {
    "strickler": (1.0, 200.0, "m^(1/3)/s"),
    "manning": (0.005, 1.0, "s/m^(1/3)"),
    "chezy": (1.0, 300.0, "m^(1/2)/s"),
    "white-colebrook": (1.0e-6, 1.0, "m"),
}

FrictionType = Literal["strickler", "manning", "chezy", "white-colebrook"]


class Friction(NetworkModel):
    """Bed friction law and coefficient.

    Attributes
    ----------
    type
        ``strickler`` (k_s in m^(1/3)/s, C = k_s R^(1/6), thesis Eq. 3-3), ``manning`` (n in
        s/m^(1/3), C = R^(1/6)/n), ``chezy`` (C in m^(1/2)/s) or ``white-colebrook`` (equivalent
        sand roughness k_n in m, C = 18 log10(12 R / k_n), the rough-turbulent White-Colebrook law of
        D-Flow FM).
    value
        The coefficient, in the unit of its type; it must lie in the plausible range of
        :data:`FRICTION_RANGES` (this catches a Manning n given as a Strickler k_s).
    """

    type: FrictionType = Field(
        default="strickler",
        description="friction law: 'strickler' (k_s, m^(1/3)/s), 'manning' (n, s/m^(1/3)), 'chezy' (C, m^(1/2)/s) "
        "or 'white-colebrook' (k_n, m)",
    )
    value: Real = Field(
        gt=0,
        description="friction coefficient in the unit of its type (Strickler k_s 1-200 m^(1/3)/s, "
        "Manning n 0.005-1 s/m^(1/3), Chezy C 1-300 m^(1/2)/s, White-Colebrook k_n 1e-6-1 m)",
    )

    @model_validator(mode="after")
    def _plausible(self) -> Friction:
        _check_range(self.type, self.value, "value")
        return self


def _check_range(kind: str, value: float, path: str) -> None:
    """Raise :class:`FieldProblem` at ``path`` when ``value`` lies outside the plausible range of ``kind``."""
    low, high, unit = FRICTION_RANGES[kind]
    if low <= value <= high:
        return
    hint = ""
    if kind == "strickler" and value < low:
        hint = '; is it a Manning n? then write type = "manning"'
    elif kind == "manning" and value > high:
        hint = '; is it a Strickler k_s? then write type = "strickler"'
    raise FieldProblem(
        path,
        f"{kind} coefficient {num(value)} {unit} is outside the plausible range {num(low)}-{num(high)} {unit}{hint}",
    )


class BranchFriction(NetworkModel):
    """The value a friction group takes on one branch instead of the group's own value.

    Attributes
    ----------
    branch
        Branch id.
    value
        The coefficient on that branch, in the unit of the group's law.
    """

    branch: Identifier = Field(description="id of the branch")
    value: Real = Field(gt=0, description="friction coefficient on that branch, in the unit of the group's type")


class FrictionGroup(NetworkModel):
    """A named friction group (a D-Flow FM roughness id) that profiles refer to, section by section.

    Attributes
    ----------
    id
        Group id (calibration target ``friction:group:<id>``).
    type, value
        Friction law and coefficient, as in :class:`Friction`.
    branches
        Branches on which the group has another value (the law stays the group's).
    """

    id: Identifier = Field(description="friction group id, referred to by profiles' friction")
    type: FrictionType = Field(description="friction law, as in [friction]")
    value: Real = Field(gt=0, description="friction coefficient in the unit of its type")
    branches: list[BranchFriction] = Field(
        default=[], description="branches on which the group takes another value (same law)"
    )

    @model_validator(mode="after")
    def _plausible(self) -> FrictionGroup:
        _check_range(self.type, self.value, "value")
        seen: set[str] = set()
        for i, b in enumerate(self.branches):
            _check_range(self.type, b.value, f"branches[{i}].value")
            if b.branch in seen:
                raise FieldProblem(f"branches[{i}].branch", f"branch {b.branch!r} is listed twice")
            seen.add(b.branch)
        return self

    def value_on(self, branch_id: str) -> float:
        """The coefficient of this group on a branch (its own value unless the branch has another)."""
        for b in self.branches:
            if b.branch == branch_id:
                return b.value
        return self.value
