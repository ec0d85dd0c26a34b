"""Cross-section shapes: rectangular, trapezoidal, circular, tabulated level-width ("ZW") and surveyed ("YZ") profiles.

A profile may name the friction groups (``[[friction_groups]]``) of its sections; a profile without
them takes the friction of the branch it lies on (or the global friction).
"""

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
    nums,
    same_length,
    strictly_increasing,
    tiny,
)

__all__ = [
    "CircularProfile",
    "Profile",
    "RectangularProfile",
    "SummerDike",
    "TrapezoidalProfile",
    "YZProfile",
    "ZWProfile",
    "profile_sections",
]

_FRICTION = (
    "friction groups of the profile's sections (ids of [[friction_groups]]); default: the branch's friction"
)


def _one_friction(friction: list[str] | None, what: str) -> None:
    if friction is not None and len(friction) != 1:
        raise FieldProblem("friction", f"a {what} profile has one friction section, so friction takes one group id, "
                                       f"got {len(friction)}")



class RectangularProfile(NetworkModel):
    """Rectangular cross-section.

    Attributes
    ----------
    width
        Bottom (= flow) width, m.
    height
        Bank height above the bed, m (optional; used for freeboard checks and plots); the inside
        height of a closed profile.
    closed
        A closed conduit (a box culvert or sewer): no width above ``height``.
    friction
        The friction group of the profile (one id); default: the branch's friction.
    """

    id: Identifier
    type: Literal["rectangular"] = Field(description="profile type 'rectangular'")
    width: Size = Field(ge=MIN_SIZE, description="width of the channel, m")
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional)")
    closed: bool = Field(default=False, description="a closed conduit of this width and height (needs height)")
    friction: list[Identifier] | None = Field(default=None, min_length=1, description=_FRICTION)

    @model_validator(mode="after")
    def _check(self) -> RectangularProfile:
        if self.closed and self.height is None:
            raise FieldProblem("height", "a closed rectangular profile needs its inside height (m)")
        _one_friction(self.friction, "rectangular")
        return self


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
    friction
        The friction group of the profile (one id); default: the branch's friction.
    """

    id: Identifier
    type: Literal["trapezoidal"] = Field(description="profile type 'trapezoidal'")
    bottom_width: Size = Field(ge=0, description="width of the bed, m (0 for a V-shaped channel)")
    side_slope: Real = Field(
        ge=0, le=1000, description="horizontal run per metre rise of each bank, m/m (1.5 means 1:1.5; 0 = vertical)"
    )
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="bank height above the bed, m (optional)")
    friction: list[Identifier] | None = Field(default=None, min_length=1, description=_FRICTION)

    @model_validator(mode="after")
    def _not_degenerate(self) -> TrapezoidalProfile:
        _one_friction(self.friction, "trapezoidal")
        if self.bottom_width == 0 and self.side_slope == 0:
            raise FieldProblem("bottom_width", "bottom_width and side_slope are both 0: the profile has no width")
        if 0 < self.bottom_width < MIN_SIZE:
            raise FieldProblem("bottom_width", tiny(self.bottom_width, "m", MIN_SIZE))
        if 0 < self.side_slope < MIN_SIZE:
            raise FieldProblem(
                "side_slope", f"{num(self.side_slope)} m/m is neither 0 (vertical banks) nor at least {num(MIN_SIZE)}"
            )
        return self


class SummerDike(NetworkModel):
    """A summer dike on a floodplain of a zw profile (SOBEK 3 ``sd_*``, D-Flow FM ``levee*``).

    The area behind the dike takes part in the flow and stores water only once the water tops the crest:
    both areas grow from 0 at the crest to their full value at ``transition`` above it (smoothly, two
    parabolas: SOBEK 3's summer dike). The flow area adds no wetted perimeter. Once the dike has been topped
    by the whole transition, the storage behind it drains along another curve, the same two parabolas
    from its full value at crest + transition down to 0 at ``base`` (the floodplain behind it: the water
    stays there until the river falls below the dike), and fills again along the first curve once the
    level has fallen to ``base`` (SOBEK 3's hysteresis of the summer dike's total area).

    Attributes
    ----------
    crest
        Height of the crest above the profile's lowest point, m.
    flow_area
        Flow area behind the dike when it is full, m².
    total_area
        Total (storage) area behind the dike when it is full, m² (at least the flow area).
    transition
        Height over which the areas fill above the crest, m (SOBEK 3's TransitionHeightSD, 0.5 m).
    base
        Height of the floodplain behind the dike above the profile's lowest point, m (SOBEK 3's
        ``sd_baseLevel``), at most the crest; the storage drains down to it on a falling limb. Default: the
        crest (the storage fills and drains along the same curve).
    """

    crest: Size = Field(ge=0, description="height of the crest above the profile's lowest point, m")
    flow_area: Size = Field(ge=0, description="flow area behind the dike when full, m²")
    total_area: Size = Field(ge=0, description="total (storage) area behind the dike when full, m²")
    transition: Size = Field(default=0.5, ge=MIN_SIZE, description="height over which the areas fill above "
                                                                     "the crest, m")
    base: Size | None = Field(default=None, ge=0, description="height of the floodplain behind the dike above the "
                                                              "profile's lowest point, m (at most the crest; the "
                                                              "storage drains down to it on a falling limb; "
                                                              "default: the crest)")

    @model_validator(mode="after")
    def _check(self) -> SummerDike:
        if self.total_area < self.flow_area:
            raise FieldProblem("total_area", f"the total area {num(self.total_area)} m² is smaller than the flow "
                                             f"area {num(self.flow_area)} m²")
        if self.base is not None and self.base > self.crest:
            raise FieldProblem("base", f"the base {num(self.base)} m lies above the crest {num(self.crest)} m")
        return self

    @property
    def floor(self) -> float:
        """The height the storage drains down to on a falling limb, m (:attr:`base`, or the crest)."""
        return self.crest if self.base is None else float(self.base)


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
    closed
        A closed conduit (a sewer pipe): the widths may narrow upward, and above the last height
        the conduit is closed. In an open profile with ``total_widths`` the flow widths may narrow
        (part of the width stops conveying and only stores); the total widths may not.
    section_widths
        Widths of the main channel and of up to two floodplains (m) that split the flow width into
        friction sections (D-Flow FM "zwRiver"): the flow width is filled main channel first.
    friction
        Friction group of each section (one id per section); default: the branch's friction.
    summer_dike
        A summer dike on the floodplain (:class:`SummerDike`).
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
    closed: bool = Field(default=False, description="a closed conduit: widths may narrow, closed above the table")
    section_widths: list[Size] | None = Field(
        default=None, min_length=1, max_length=3,
        description="flow widths of the main channel and up to two floodplains, m (friction sections)",
    )
    friction: list[Identifier] | None = Field(default=None, min_length=1, description=_FRICTION)
    summer_dike: SummerDike | None = Field(default=None, description="a summer dike on the floodplain (optional)")

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
            if not self.closed and (name == "total_widths" or self.total_widths is None):
                non_decreasing(widths, name, "m", "an open profile cannot narrow upward (set closed = true for a pipe"
                                                  "; give total_widths for a flow width that narrows)")
        if not self.closed and self.flow_widths[-1] <= 0:
            raise FieldProblem(
                f"flow_widths[{len(self.flow_widths) - 1}]",
                "the top flow width must be positive, otherwise the profile cannot convey flow",
            )
        if max(self.flow_widths) <= 0:
            raise FieldProblem("flow_widths", "all flow widths are 0: the profile cannot convey flow")
        if self.section_widths is not None:
            top = max(self.flow_widths)
            if sum(self.section_widths) < top - MIN_SIZE:
                raise FieldProblem(
                    "section_widths",
                    f"the sections {nums(self.section_widths)} m together are narrower than the widest flow width "
                    f"{num(top)} m; they must cover it",
                )
            if self.section_widths[0] < MIN_SIZE:
                raise FieldProblem("section_widths[0]", "the main channel must have a width (at least 1 mm)")
        sections = len(self.section_widths) if self.section_widths is not None else 1
        if self.friction is not None and len(self.friction) != sections:
            raise FieldProblem("friction", f"the profile has {sections} friction section(s) but friction names "
                                           f"{len(self.friction)} group(s); give one per section")
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


class CircularProfile(NetworkModel):
    """A circular closed conduit (a pipe).

    Attributes
    ----------
    diameter
        Inside diameter, m.
    friction
        The friction group of the profile (one id); default: the branch's friction.
    """

    id: Identifier
    type: Literal["circular"] = Field(description="profile type 'circular' (a closed pipe)")
    diameter: Size = Field(ge=MIN_SIZE, description="inside diameter, m")
    friction: list[Identifier] | None = Field(default=None, min_length=1, description=_FRICTION)

    @model_validator(mode="after")
    def _check(self) -> CircularProfile:
        _one_friction(self.friction, "circular")
        return self


class YZProfile(NetworkModel):
    """A surveyed cross-section: horizontal positions and heights of the bed, relative to its lowest point.

    The conveyance is computed as D-Flow FM does for yz profiles: ``segmented`` sums the conveyance
    of each piece between two survey points (each with its own depth and hydraulic radius), which
    keeps shallow banks from lowering the conveyance of the deep channel; ``lumped`` uses the
    hydraulic radius A/P of each friction section as a whole. Above the highest of the two end
    points the walls are vertical.

    Attributes
    ----------
    y
        Horizontal positions across the section, m, non-decreasing (equal values make a vertical wall).
    z
        Height of the bed at each position above the lowest point, m (the lowest is 0); its level
        is the cross-section's ``bed_level``.
    conveyance
        ``segmented`` (default) or ``lumped``.
    friction_positions
        Positions y (m) that bound the friction sections, from the first y to the last.
    friction
        Friction group of each section (one id per section); default: the branch's friction.
    """

    id: Identifier
    type: Literal["yz"] = Field(description="profile type 'yz' (a surveyed cross-section)")
    y: list[Real] = Field(min_length=2, description="horizontal positions across the section, m, non-decreasing")
    z: list[Size] = Field(min_length=2, description="height of the bed above the lowest point at each y, m")
    conveyance: Literal["segmented", "lumped"] = Field(
        default="segmented", description="'segmented' (conveyance summed piece by piece) or 'lumped' (A/P per section)"
    )
    friction_positions: list[Real] | None = Field(
        default=None, min_length=2, description="y positions that bound the friction sections, m, from first to last y"
    )
    friction: list[Identifier] | None = Field(default=None, min_length=1, description=_FRICTION)

    @model_validator(mode="after")
    def _check(self) -> YZProfile:
        same_length(self.y, "y", self.z, "z")
        non_decreasing(self.y, "y", "m", "positions run from one bank to the other")
        non_negative(self.z, "z", "m")
        if min(self.z) != 0.0:
            raise FieldProblem(
                "z", f"heights are measured from the lowest point of the profile, so the lowest must be 0, got "
                     f"{num(min(self.z))} m (the level of that point is the cross-section's bed_level)")
        if self.y[-1] - self.y[0] < MIN_SIZE:
            raise FieldProblem("y", "the profile has no width: the first and last y are the same")
        sections = 1
        if self.friction_positions is not None:
            pos = self.friction_positions
            strictly_increasing(pos, "friction_positions", "m")
            tol = 1e-6 * max(1.0, abs(self.y[0]), abs(self.y[-1]))
            if abs(pos[0] - self.y[0]) > tol or abs(pos[-1] - self.y[-1]) > tol:
                raise FieldProblem(
                    "friction_positions",
                    f"the friction sections must run from the first y ({num(self.y[0])} m) to the last "
                    f"({num(self.y[-1])} m), got {nums(pos)}",
                )
            sections = len(pos) - 1
        if self.friction is not None and len(self.friction) != sections:
            raise FieldProblem("friction", f"the profile has {sections} friction section(s) but friction names "
                                           f"{len(self.friction)} group(s); give one per section")
        return self


Profile = Annotated[
    RectangularProfile | TrapezoidalProfile | CircularProfile | ZWProfile | YZProfile, Field(discriminator="type")
]


def profile_sections(profile: RectangularProfile | TrapezoidalProfile | CircularProfile | ZWProfile | YZProfile) -> int:
    """Number of friction sections of a profile."""
    if isinstance(profile, ZWProfile) and profile.section_widths is not None:
        return len(profile.section_widths)
    if isinstance(profile, YZProfile) and profile.friction_positions is not None:
        return len(profile.friction_positions) - 1
    return 1

