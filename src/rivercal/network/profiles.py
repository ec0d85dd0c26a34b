"""Cross-section shapes: rectangular, trapezoidal and tabulated level-width ("ZW") profiles."""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import (
    MIN_SIZE,
    Identifier,
    NetworkModel,
    Real,
    Size,
    non_decreasing,
    non_negative,
    num,
    same_length,
    strictly_increasing,
    tiny,
)

__all__ = ["Profile", "RectangularProfile", "TrapezoidalProfile", "ZWProfile"]



class RectangularProfile(NetworkModel):
    """Rectangular cross-section.

    Attributes
    ----------
    width
        Bottom (= flow) width, m.
    height
        Bank height above the bed, m (optional; used for freeboard checks and plots).
    """

    id: Identifier
    type: Literal["rectangular"] = Field(description="profile type 'rectangular'")
    width: Size = Field(ge=MIN_SIZE, description="width of the channel, m")
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional)")


class TrapezoidalProfile(NetworkModel):
    """Trapezoidal cross-section.

    Attributes
    ----------
    bottom_width
        Width of the bed, m.
    side_slope
        Horizontal run per unit rise of each bank, m/m (0 gives a rectangle).
    height
        Bank height above the bed, m (optional). The table used by the engine extends the banks
        up to ``max(height, 10 m)`` and continues with vertical walls above.
    """

    id: Identifier
    type: Literal["trapezoidal"] = Field(description="profile type 'trapezoidal'")
    bottom_width: Size = Field(ge=0, description="width of the bed, m (0 for a V-shaped channel)")
    side_slope: Real = Field(
        ge=0, le=1000, description="horizontal run per metre rise of each bank, m/m (1.5 means 1:1.5; 0 = vertical)"
    )
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional)")

    @model_validator(mode="after")
    def _not_degenerate(self) -> TrapezoidalProfile:
        if self.bottom_width == 0 and self.side_slope == 0:
            raise FieldProblem("bottom_width", "bottom_width and side_slope are both 0: the profile has no width")
        if 0 < self.bottom_width < MIN_SIZE:
            raise FieldProblem("bottom_width", tiny(self.bottom_width, "m", MIN_SIZE))
        if 0 < self.side_slope < MIN_SIZE:
            raise FieldProblem(
                "side_slope", f"{num(self.side_slope)} m/m is neither 0 (vertical banks) nor at least {num(MIN_SIZE)}"
            )
        return self


class ZWProfile(NetworkModel):
    """Tabulated level-width ("ZW") cross-section, relative to its own lowest point.

    Attributes
    ----------
    heights
        Heights above the bed, m; start at 0 and strictly increase.
    flow_widths
        Width that conveys flow at each height, m; non-negative and non-decreasing.
    total_widths
        Width that stores water at each height, m (default: the flow widths); not smaller than
        the flow width, non-decreasing.
    height
        Bank height above the bed, m (optional): the top of the main channel, above which water
        spreads over the floodplain part of the table.
    """

    id: Identifier
    type: Literal["zw"] = Field(description="profile type 'zw' (tabulated heights and widths)")
    heights: list[Size] = Field(
        min_length=2, description="heights above the lowest point of the profile, m; start at 0, strictly increasing"
    )
    flow_widths: list[Size] = Field(
        min_length=2, description="width that conveys flow at each height, m; non-negative, non-decreasing"
    )
    total_widths: list[Size] | None = Field(
        default=None,
        description="width that stores water at each height, m (default: flow_widths); not below the flow width",
    )
    height: Size | None = Field(
        default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional; top of the main channel)"
    )

    @model_validator(mode="after")
    def _check_table(self) -> ZWProfile:
        same_length(self.heights, "heights", self.flow_widths, "flow_widths")
        if self.total_widths is not None:
            same_length(self.heights, "heights", self.total_widths, "total_widths")
        if self.heights[0] != 0.0:
            raise FieldProblem(
                "heights[0]",
                f"heights are measured from the lowest point of the profile and must start at 0, got "
                f"{num(self.heights[0])} m (the level of that point is the cross-section's bed_level)",
            )
        strictly_increasing(self.heights, "heights", "m")
        for name, widths in (("flow_widths", self.flow_widths), ("total_widths", self.total_widths)):
            if widths is None:
                continue
            non_negative(widths, name, "m")
            for i, w in enumerate(widths):
                if 0 < w < MIN_SIZE:
                    raise FieldProblem(f"{name}[{i}]", tiny(w, "m", MIN_SIZE))
            non_decreasing(widths, name, "m", "a profile cannot narrow upward")
        if self.flow_widths[-1] <= 0:
            raise FieldProblem(
                f"flow_widths[{len(self.flow_widths) - 1}]",
                "the top flow width must be positive, otherwise the profile cannot convey flow",
            )
        if self.total_widths is not None:
            for i, (t, f) in enumerate(zip(self.total_widths, self.flow_widths, strict=True)):
                if t < f:
                    raise FieldProblem(
                        f"total_widths[{i}]",
                        f"total (storage) width {num(t)} m is smaller than the flow width {num(f)} m at height "
                        f"{num(self.heights[i])} m",
                    )
        return self

    @property
    def storage_widths(self) -> list[float]:
        """Total (storage) widths, m."""
        return list(self.total_widths if self.total_widths is not None else self.flow_widths)


Profile = Annotated[RectangularProfile | TrapezoidalProfile | ZWProfile, Field(discriminator="type")]

