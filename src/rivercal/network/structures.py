"""Structures on a branch: weirs, culverts and pumps."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import (
    MIN_SIZE,
    Discharge,
    FlowDirection,
    Identifier,
    Level,
    NetworkModel,
    Real,
    Size,
    num,
)
from rivercal.network.friction import Friction

__all__ = ["Culvert", "Pump", "Weir"]



class _OnBranch(NetworkModel):
    id: Identifier = Field(description="structure id, unique among weirs, culverts and pumps")
    branch: Identifier = Field(description="id of the branch the structure sits on")
    chainage: Real = Field(ge=0, description="distance from the start of the branch, m")


class Weir(_OnBranch):
    """A broad-crested weir (thesis Eq. 3-4, free/submerged switch at h1 - zs = 1.5 (h2 - zs)).

    Attributes
    ----------
    crest_level
        Crest level z_s, m AD (a calibration target: ``weir:<id>.crest_level``); not below the bed.
    crest_width
        Crest width W_s, m.
    discharge_coefficient
        c_e, dimensionless.
    lateral_contraction
        c_w, dimensionless.
    allowed_flow
        ``both``, ``positive`` (branch direction only), ``negative`` or ``none``.
    """

    crest_level: Level = Field(description="crest level, m AD (not below the bed at the weir)")
    crest_width: Size = Field(ge=MIN_SIZE, description="crest width, m")
    discharge_coefficient: Real = Field(default=1.0, gt=0, le=2.0, description="discharge coefficient c_e, -")
    lateral_contraction: Real = Field(default=1.0, gt=0, le=1.0, description="lateral contraction coefficient c_w, -")
    allowed_flow: FlowDirection = Field(
        default="both", description="flow directions let through: 'both', 'positive', 'negative' or 'none'"
    )


class Culvert(_OnBranch):
    """A culvert: a closed conduit with entrance, friction and exit losses.

    Attributes
    ----------
    shape
        ``rectangular`` (``width`` x ``height``) or ``circular`` (``diameter``).
    width, height, diameter
        Conduit dimensions, m.
    invert_level
        Level of the conduit's bottom, m AD; not below the bed.
    length
        Conduit length, m.
    inlet_loss, outlet_loss
        Entrance and exit loss coefficients, dimensionless.
    friction
        Wall friction (default Manning n = 0.015 s/m^(1/3), concrete).
    allowed_flow
        ``both``, ``positive``, ``negative`` or ``none``.
    """

    shape: Literal["rectangular", "circular"] = Field(description="'rectangular' (width x height) or 'circular'")
    width: Size | None = Field(default=None, ge=MIN_SIZE, description="inside width of a rectangular culvert, m")
    height: Size | None = Field(default=None, ge=MIN_SIZE, description="inside height of a rectangular culvert, m")
    diameter: Size | None = Field(default=None, ge=MIN_SIZE, description="inside diameter of a circular culvert, m")
    invert_level: Level = Field(description="level of the conduit's bottom, m AD (not below the bed)")
    length: Size = Field(ge=MIN_SIZE, description="length of the conduit, m")
    inlet_loss: Real = Field(default=0.5, ge=0, description="entrance loss coefficient, -")
    outlet_loss: Real = Field(default=1.0, ge=0, description="exit loss coefficient, -")
    friction: Friction = Field(
        default=Friction(type="manning", value=0.015), description="wall friction (default Manning n = 0.015)"
    )
    allowed_flow: FlowDirection = Field(
        default="both", description="flow directions let through: 'both', 'positive', 'negative' or 'none'"
    )

    @model_validator(mode="after")
    def _dimensions(self) -> Culvert:
        if self.shape == "rectangular":
            for name in ("width", "height"):
                if getattr(self, name) is None:
                    raise FieldProblem(name, f"a rectangular culvert needs {name} (m)")
            if self.diameter is not None:
                raise FieldProblem("diameter", "a rectangular culvert has width and height, not a diameter")
        else:
            if self.diameter is None:
                raise FieldProblem("diameter", "a circular culvert needs diameter (m)")
            for name in ("width", "height"):
                if getattr(self, name) is not None:
                    raise FieldProblem(name, f"a circular culvert has a diameter, not a {name}")
        return self

    @property
    def opening_height(self) -> float:
        """Height of the conduit, m."""
        return float(self.diameter if self.shape == "circular" else self.height)  # type: ignore[arg-type]


class Pump(_OnBranch):
    """A pump with a fixed capacity and level switches on its suction side.

    Attributes
    ----------
    capacity
        Discharge when running, m³/s.
    start_level, stop_level
        Suction-side levels at which the pump switches on and off, m AD (start > stop > bed).
    direction
        ``positive`` pumps in the branch direction, ``negative`` against it.
    """

    capacity: Discharge = Field(gt=0, description="discharge when running, m³/s")
    start_level: Level = Field(description="suction-side level at which the pump starts, m AD")
    stop_level: Level = Field(description="suction-side level at which the pump stops, m AD (below start_level)")
    direction: Literal["positive", "negative"] = Field(
        default="positive", description="'positive' pumps in the branch direction, 'negative' against it"
    )

    @model_validator(mode="after")
    def _levels(self) -> Pump:
        if not self.start_level > self.stop_level:
            raise FieldProblem(
                "stop_level",
                f"stop_level {num(self.stop_level)} m AD must be below start_level {num(self.start_level)} m AD",
            )
        return self


