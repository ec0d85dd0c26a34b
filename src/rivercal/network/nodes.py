"""Connection nodes and their storage (a constant area or a level-area table)."""

from __future__ import annotations

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import (
    Identifier,
    Level,
    NetworkModel,
    Real,
    non_decreasing,
    non_negative,
    same_length,
    strictly_increasing,
)

__all__ = ["Node", "StorageTable"]



class StorageTable(NetworkModel):
    """Storage area of a connection node as a function of level.

    Attributes
    ----------
    levels
        Water levels, m AD, strictly increasing.
    areas
        Horizontal storage area at each level, m², non-negative and non-decreasing. Linear in
        between; constant above the last level; zero below the first.
    """

    levels: list[Level] = Field(min_length=2, description="water levels, m AD, strictly increasing")
    areas: list[Real] = Field(
        min_length=2, description="horizontal storage area at each level, m²; non-negative, non-decreasing"
    )

    @model_validator(mode="after")
    def _check(self) -> StorageTable:
        same_length(self.levels, "levels", self.areas, "areas")
        strictly_increasing(self.levels, "levels", "m AD")
        non_negative(self.areas, "areas", "m²")
        non_decreasing(self.areas, "areas", "m²", "the storage area cannot shrink as the water rises")
        if self.areas[-1] <= 0:
            raise FieldProblem(f"areas[{len(self.areas) - 1}]", "all storage areas are 0: the table stores no water")
        return self


class Node(NetworkModel):
    """A connection node: the end of one or more branches.

    Attributes
    ----------
    x, y
        Map coordinates, m (optional, both or neither; used for plots).
    storage_area
        Extra horizontal storage area at the node, m² (a pond or a manhole), from the lowest bed
        level of the attached branches upward.
    storage_table
        Extra storage as a level-area table (alternative to ``storage_area``).
    """

    id: Identifier
    x: Real | None = Field(default=None, description="map x coordinate, m (optional)")
    y: Real | None = Field(default=None, description="map y coordinate, m (optional)")
    storage_area: Real = Field(
        default=0.0, ge=0, description="extra storage area at the node, m² (a pond), from the lowest bed level up"
    )
    storage_table: StorageTable | None = Field(
        default=None, description="extra storage as a level-area table (instead of storage_area)"
    )

    @model_validator(mode="after")
    def _one_storage(self) -> Node:
        if self.storage_table is not None and self.storage_area > 0:
            raise FieldProblem("storage_table", "give either storage_area or storage_table, not both")
        if (self.x is None) != (self.y is None):
            raise FieldProblem("x" if self.x is None else "y", "give both map coordinates x and y, or neither")
        return self


