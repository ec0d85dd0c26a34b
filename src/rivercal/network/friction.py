"""Bed friction: the law and its coefficient with a plausible range, and the friction groups profiles refer to.

The laws: Strickler, Manning, Chézy and White-Colebrook.
"""

from __future__ import annotations

import functools
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import Identifier, NetworkModel, Real, num, strictly_increasing

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
    """The friction a group takes on one branch instead of the group's own value.

    One of three forms (D-Flow FM's and SOBEK 3's roughness of a branch):

    - ``value``: one coefficient along the whole branch;
    - ``chainages`` and ``values``: coefficients at chainages, linear between them and constant beyond the
      first and the last (D-Flow FM 1D, SOBEK 3);
    - ``function = "waterlevel"`` with ``levels`` and ``table``: coefficients that depend on the water level, one
      row per chainage (or one row for the whole branch without ``chainages``), linear in the level between the
      given levels and constant beyond them, and linear in the chainage between the rows.

    Attributes
    ----------
    branch
        Branch id.
    type
        The friction law of these coefficients (default: the group's law). A law of its own is exact: the
        conveyance of the section is computed with it.
    value
        A constant coefficient on that branch, in the unit of the law.
    chainages
        Chainages (m from the start of the branch, strictly increasing) of ``values`` or of the rows of ``table``.
    values
        Coefficients at ``chainages``, unit of the law.
    function
        ``constant`` (default) or ``waterlevel``.
    levels
        Water levels of the columns of ``table``, m AD, strictly increasing.
    table
        Per chainage (one row without ``chainages``), the coefficient at each of ``levels``.
    """

    branch: Identifier = Field(description="id of the branch")
    type: FrictionType | None = Field(
        default=None, description="friction law of these coefficients (default: the group's law)"
    )
    value: Real | None = Field(default=None, gt=0, description="friction coefficient on that branch, unit of the law")
    chainages: list[Real] | None = Field(
        default=None, min_length=1,
        description="chainages of values (or of the rows of table), m from the start of the branch, increasing",
    )
    values: list[Real] | None = Field(
        default=None, min_length=1, description="coefficient at each chainage, unit of the law (linear between)"
    )
    function: Literal["constant", "waterlevel"] = Field(
        default="constant", description="'constant', or 'waterlevel': the coefficient depends on the water level"
    )
    levels: list[Real] | None = Field(
        default=None, min_length=1, description="water levels of the columns of table, m AD, strictly increasing"
    )
    table: list[list[Real]] | None = Field(
        default=None, min_length=1,
        description="per chainage (one row without chainages) the coefficient at each level, unit of the law",
    )

    @model_validator(mode="after")
    def _one_form(self) -> BranchFriction:
        if self.function == "waterlevel":
            for name in ("value", "values"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a water-level dependent friction takes levels and table, not {name}")
            if self.levels is None or self.table is None:
                raise FieldProblem("levels" if self.levels is None else "table",
                                   "a water-level dependent friction needs levels (m AD) and a table of coefficients")
            strictly_increasing(self.levels, "levels", "m AD")
            rows = len(self.chainages) if self.chainages is not None else 1
            if len(self.table) != rows:
                raise FieldProblem("table", f"the table has {len(self.table)} row(s) but there are {rows} "
                                            f"chainage(s); give one row per chainage (one row without chainages)")
            for i, row in enumerate(self.table):
                if len(row) != len(self.levels):
                    raise FieldProblem(f"table[{i}]", f"row {i} has {len(row)} values but there are "
                                                      f"{len(self.levels)} levels; give one value per level")
                for j, v in enumerate(row):
                    if not v > 0:
                        raise FieldProblem(f"table[{i}][{j}]", f"friction coefficients must be positive, got {num(v)}")
        else:
            for name in ("levels", "table"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"{name} belongs to a water-level dependent friction (function = "
                                             "'waterlevel')")
            if (self.value is None) == (self.values is None):
                raise FieldProblem("value", "give either value (one coefficient along the branch) or chainages "
                                            "and values (coefficients along the branch), not both or neither")
            if self.values is not None:
                if self.chainages is None:
                    raise FieldProblem("chainages", "values along the branch need their chainages (m)")
                if len(self.values) != len(self.chainages):
                    raise FieldProblem("values", f"{len(self.values)} values for {len(self.chainages)} chainages; "
                                                 "give one value per chainage")
                for i, v in enumerate(self.values):
                    if not v > 0:
                        raise FieldProblem(f"values[{i}]", f"friction coefficients must be positive, got {num(v)}")
            elif self.chainages is not None:
                raise FieldProblem("chainages", "chainages belong to values along the branch (or to the rows of a "
                                                "table), not to one value")
        if self.chainages is not None:
            if self.chainages[0] < 0:
                raise FieldProblem("chainages[0]", f"chainages are m from the start of the branch, got "
                                                   f"{num(self.chainages[0])} m")
            strictly_increasing(self.chainages, "chainages", "m")
        return self

    @property
    def varies(self) -> bool:
        """Whether the coefficient varies along the branch or with the water level."""
        return self.function != "constant" or self.values is not None

    def check_range(self, law: str, path: str = "") -> None:
        """Raise :class:`FieldProblem` unless the coefficients are plausible for ``law``.

        A constant value and values along the branch must each lie in the range of the law; a level table must
        have its largest coefficient in it (a whole table in another unit is caught, while the low values a
        table gives a dry floodplain stay as they are).
        """
        prefix = f"{path}." if path else ""
        if self.value is not None:
            _check_range(law, self.value, f"{prefix}value")
        for i, v in enumerate(self.values or []):
            _check_range(law, v, f"{prefix}values[{i}]")
        if self.table is not None:
            top = max(max(row) for row in self.table)
            _check_range(law, top, f"{prefix}table")

    @functools.cached_property
    def _arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """The levels (m AD) and the table as arrays, made once."""
        return np.asarray(self.levels, dtype=float), np.asarray(self.table, dtype=float)

    def coefficient_at(self, chainage: float) -> tuple[np.ndarray | None, np.ndarray]:
        """The coefficient at a chainage (m): ``(None, [c])`` when constant in level, else ``(levels, c(levels))``.

        Linear between chainages and constant beyond the first and last (D-Flow FM 1D, SOBEK 3).
        """
        if self.function == "waterlevel":
            levels, rows = self._arrays
            if self.chainages is None or len(self.chainages) == 1:
                return levels, rows[0].copy()
            ch = np.asarray(self.chainages, dtype=float)
            j = int(np.clip(np.searchsorted(ch, chainage, side="right") - 1, 0, ch.size - 2))
            w = float(np.clip((chainage - ch[j]) / (ch[j + 1] - ch[j]), 0.0, 1.0))
            return levels, (1.0 - w) * rows[j] + w * rows[j + 1]
        if self.values is not None:
            return None, np.array([float(np.interp(chainage, self.chainages, self.values))])
        return None, np.array([float(self.value)])


class FrictionGroup(NetworkModel):
    """A named friction group (a D-Flow FM roughness id) that profiles refer to, section by section.

    Attributes
    ----------
    id
        Group id (calibration target ``friction:group:<id>``).
    type, value
        Friction law and coefficient, as in :class:`Friction`.
    branches
        Branches on which the group takes other values: a value, values along the branch or a water-level
        table, in the group's law or one of their own (:class:`BranchFriction`).
    """

    id: Identifier = Field(description="friction group id, referred to by profiles' friction")
    type: FrictionType = Field(description="friction law, as in [friction]")
    value: Real = Field(gt=0, description="friction coefficient in the unit of its type")
    branches: list[BranchFriction] = Field(
        default=[], description="branches on which the group takes other values (a value, values along the branch "
                                "or a water-level table; its own law or the group's)"
    )

    @model_validator(mode="after")
    def _plausible(self) -> FrictionGroup:
        _check_range(self.type, self.value, "value")
        seen: set[str] = set()
        for i, b in enumerate(self.branches):
            b.check_range(b.type or self.type, f"branches[{i}]")
            if b.branch in seen:
                raise FieldProblem(f"branches[{i}].branch", f"branch {b.branch!r} is listed twice")
            seen.add(b.branch)
        return self

    def entry(self, branch_id: str) -> BranchFriction | None:
        """The group's entry for a branch, or None when the branch takes the group's own value."""
        for b in self.branches:
            if b.branch == branch_id:
                return b
        return None

    def value_on(self, branch_id: str) -> float:
        """The constant coefficient of this group on a branch (its own value unless the branch has another).

        Raises
        ------
        ValueError
            When the branch's coefficient varies along it or with the level (see :meth:`entry`).
        """
        b = self.entry(branch_id)
        if b is None:
            return self.value
        if b.value is None:
            raise ValueError(f"friction group {self.id!r} varies along branch {branch_id!r} or with the level")
        return b.value
