"""Forcing: boundary conditions at end nodes, laterals, and the time series they read.

A boundary imposes a discharge, a level or a Q(h) rating at an end node; a lateral adds an inflow
(or an extraction) at a node or at a chainage on a branch.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import (
    MAX_LEVEL,
    Discharge,
    Identifier,
    Level,
    NetworkModel,
    Real,
    non_decreasing,
    non_negative,
    num,
    one_location,
    same_length,
    strictly_increasing,
)

__all__ = ["Boundary", "Lateral", "RatingTable", "SeriesRef"]


class SeriesRef(NetworkModel):
    """A column of a CSV time series file in the case folder.

    Attributes
    ----------
    file
        Path of the CSV file relative to the case folder.
    column
        Name of the value column (the first column holds the UTC times).
    """

    file: str = Field(min_length=1, description="CSV file, relative to the case folder")
    column: str = Field(min_length=1, description="name of the value column in that file")





class RatingTable(NetworkModel):
    """Outflow discharge as a function of level at a boundary node (a Q(h) relation).

    Attributes
    ----------
    levels
        Levels, m AD, strictly increasing.
    discharges
        Outflow at each level, m³/s: starting at 0 (the level at which outflow stops; below the
        table the engine keeps the first value) and non-decreasing. Above the table the last
        slope is extrapolated.
    """

    levels: list[Level] = Field(min_length=2, description="water levels, m AD, strictly increasing")
    discharges: list[Discharge] = Field(
        min_length=2, description="outflow at each level, m³/s; starts at 0, non-decreasing"
    )

    @model_validator(mode="after")
    def _check(self) -> RatingTable:
        same_length(self.levels, "levels", self.discharges, "discharges")
        strictly_increasing(self.levels, "levels", "m AD")
        non_negative(self.discharges, "discharges", "m³/s")
        non_decreasing(self.discharges, "discharges", "m³/s", "the outflow cannot fall as the level rises")
        if self.discharges[0] != 0:
            raise FieldProblem(
                "discharges[0]",
                f"the first discharge must be 0 m³/s (the level at which outflow stops), got "
                f"{num(self.discharges[0])} m³/s; below the table the outflow stays at the first value, which "
                "would drain the node even when it is dry",
            )
        return self


class Boundary(NetworkModel):
    """A boundary condition at an end node.

    Attributes
    ----------
    node
        Id of an end node (a node with exactly one branch).
    type
        ``discharge`` (inflow Q(t), m³/s, negative for outflow), ``level`` (h(t), m AD),
        ``rating`` (outflow from a Q(h) table) or ``critical`` (a free outfall: the water leaves over the end
        at the critical flow of the end's cross-section for the depth there, Q = A √(g A / T)).
    series
        Time series of the value (for ``discharge`` and ``level``).
    value
        Constant value instead of a series.
    catchment
        Id of a sub-catchment (``[[catchments]]`` of the case) whose runoff is the inflow (for
        ``discharge``).
    rating
        The Q(h) table (for ``rating``).
    """

    id: Identifier
    node: Identifier = Field(description="id of an end node (a node with exactly one branch)")
    type: Literal["discharge", "level", "rating", "critical"] = Field(
        description="'discharge' (inflow, m³/s), 'level' (water level, m AD), 'rating' (outflow from a Q(h) table) "
                    "or 'critical' (a free outfall: outflow at critical depth)"
    )
    series: SeriesRef | None = Field(default=None, description="time series of the value (discharge or level)")
    value: Discharge | None = Field(default=None, description="constant value instead of a series: m³/s or m AD")
    catchment: Identifier | None = Field(
        default=None, description="sub-catchment whose runoff (m³/s) is the inflow of a 'discharge' boundary"
    )
    rating: RatingTable | None = Field(default=None, description="the Q(h) table of a 'rating' boundary")

    @model_validator(mode="after")
    def _one_source(self) -> Boundary:
        if self.type == "critical":
            for name in ("series", "value", "catchment", "rating"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a critical boundary (a free outfall) takes its outflow from the "
                                             f"critical depth at the end node, not a {name}")
            return self
        if self.type == "rating":
            if self.rating is None:
                raise FieldProblem("rating", "a rating boundary needs a rating table (levels and discharges)")
            for name in ("series", "value", "catchment"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a rating boundary takes its outflow from the rating table, not a {name}")
        else:
            if self.rating is not None:
                raise FieldProblem("rating", f"a {self.type} boundary takes a series or a value, not a rating table")
            if self.type == "level" and self.catchment is not None:
                raise FieldProblem("catchment", "a level boundary cannot take its level from a catchment's runoff")
            given = [name for name in ("series", "value", "catchment") if getattr(self, name) is not None]
            if not given:
                raise FieldProblem("series", f"a {self.type} boundary needs a series, a constant value or a catchment")
            if len(given) > 1:
                raise FieldProblem(given[1], f"a {self.type} boundary takes one of series, value or catchment, "
                                             f"not {' and '.join(given)}")
            if self.type == "level" and self.value is not None and abs(self.value) > MAX_LEVEL:
                raise FieldProblem(
                    "value", f"level {num(self.value)} m AD lies outside ±{num(MAX_LEVEL)} m AD (levels are in m AD)"
                )
        return self


class Lateral(NetworkModel):
    """A point inflow (m³/s, negative for an extraction) at a node or at a chainage on a branch.

    Attributes
    ----------
    node
        Node id, or
    branch, chainage
        a location on a branch (the inflow goes to the nearest calculation point).
    series, value
        The discharge as a time series, or a constant, m³/s.
    catchment
        Or the id of a sub-catchment (``[[catchments]]`` of the case) whose runoff is the inflow.
    """

    id: Identifier
    node: Identifier | None = Field(
        default=None, description="node that receives the inflow (or give branch and chainage)"
    )
    branch: Identifier | None = Field(default=None, description="branch that receives the inflow")
    chainage: Real | None = Field(default=None, ge=0, description="location on the branch, m from its start")
    series: SeriesRef | None = Field(default=None, description="time series of the inflow, m³/s (negative: extraction)")
    value: Discharge | None = Field(default=None, description="constant inflow instead of a series, m³/s")
    catchment: Identifier | None = Field(default=None, description="sub-catchment whose runoff (m³/s) is the inflow")

    @model_validator(mode="after")
    def _location_and_source(self) -> Lateral:
        one_location(self.node, "node", self.branch, self.chainage, "a lateral")
        given = [name for name in ("series", "value", "catchment") if getattr(self, name) is not None]
        if not given:
            raise FieldProblem("series", "a lateral needs a series, a constant value (m³/s) or a catchment")
        if len(given) > 1:
            raise FieldProblem(given[1],
                               f"a lateral takes one of series, value or catchment, not {' and '.join(given)}")
        return self
