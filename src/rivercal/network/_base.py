"""What every network object shares: the base model, the numeric field types, the shared rules.

The numeric field types carry their limits; the rules are the ones several objects check
(monotone tables, one location).

Every rule that fails raises :class:`~rivercal.errors.FieldProblem` with the path of the offending
field relative to the object that checks it.
"""

from __future__ import annotations

import itertools
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

from rivercal.errors import FieldProblem

__all__ = [
    "MAX_DISCHARGE",
    "MAX_LEVEL",
    "MAX_SIZE",
    "MIN_SIZE",
    "Discharge",
    "FlowDirection",
    "Identifier",
    "Level",
    "NetworkModel",
    "Real",
    "Size",
    "non_decreasing",
    "non_negative",
    "num",
    "nums",
    "one_location",
    "same_length",
    "strictly_increasing",
    "tiny",
]

Identifier = Annotated[
    str,
    Field(
        min_length=1,
        max_length=64,
        pattern=r"^[A-Za-z0-9_.\-]+$",
        description="identifier: 1-64 letters, digits, '_', '-' or '.'",
    ),
]
#: Levels must lie within ±MAX_LEVEL m AD.
MAX_LEVEL = 1.0e4
#: Discharges (boundaries, laterals, pumps, ratings) must lie within ±MAX_DISCHARGE m³/s.
MAX_DISCHARGE = 1.0e6
#: Widths, heights and diameters that must be positive are at least MIN_SIZE m (1 mm) ...
MIN_SIZE = 1.0e-3
#: ... and at most MAX_SIZE m.
MAX_SIZE = 1.0e5

#: A finite number written as a number (an int is accepted; text, booleans, nan and inf are not).
Real = Annotated[float, Field(strict=True)]
#: A water or bed level, m AD.
Level = Annotated[float, Field(strict=True, ge=-MAX_LEVEL, le=MAX_LEVEL)]
#: A discharge, m³/s.
Discharge = Annotated[float, Field(strict=True, ge=-MAX_DISCHARGE, le=MAX_DISCHARGE)]
#: A width, height or diameter, m.
Size = Annotated[float, Field(strict=True, le=MAX_SIZE)]
FlowDirection = Literal["both", "positive", "negative", "none"]


class NetworkModel(BaseModel):
    """Base of every network object: unknown fields are errors, objects are frozen, numbers finite."""

    model_config = ConfigDict(extra="forbid", frozen=True, populate_by_name=True, allow_inf_nan=False)


def num(value: float) -> str:
    """A number as a user wrote it: no trailing zeros, no exponent for ordinary values."""
    return f"{value:g}"


def nums(values: list[float]) -> str:
    """A list of numbers as a user wrote them."""
    return "[" + ", ".join(num(v) for v in values) + "]"


def strictly_increasing(values: list[float], name: str, unit: str) -> None:
    """Raise :class:`FieldProblem` at the first value of ``name`` that is not above the one before."""
    for i, (a, b) in enumerate(itertools.pairwise(values), start=1):
        if not b > a:
            raise FieldProblem(
                f"{name}[{i}]",
                f"{name} must increase strictly, but {num(b)} {unit} (position {i}) is not above "
                f"{num(a)} {unit} (position {i - 1}) in {nums(values)}",
            )


def non_decreasing(values: list[float], name: str, unit: str, why: str) -> None:
    """Raise :class:`FieldProblem` at the first value of ``name`` below the one before; ``why`` says why not."""
    for i, (a, b) in enumerate(itertools.pairwise(values), start=1):
        if b < a:
            raise FieldProblem(
                f"{name}[{i}]",
                f"{name} must not decrease, but {num(b)} {unit} (position {i}) is below {num(a)} {unit} "
                f"(position {i - 1}) in {nums(values)}; {why}",
            )


def non_negative(values: list[float], name: str, unit: str) -> None:
    """Raise :class:`FieldProblem` at the first negative value of ``name``."""
    for i, v in enumerate(values):
        if v < 0:
            raise FieldProblem(f"{name}[{i}]", f"{name} must not be negative, got {num(v)} {unit} at position {i}")


def tiny(value: float, unit: str, least: float) -> str:
    """The reason given for a size that is neither 0 nor at least ``least`` (almost always a unit mix-up)."""
    return f"{num(value)} {unit} is neither 0 nor at least {num(least)} {unit}; values are in metres"


def same_length(a: list, a_name: str, b: list, b_name: str) -> None:
    """Raise :class:`FieldProblem` on ``b_name`` unless it has one value per value of ``a_name``."""
    if len(a) != len(b):
        raise FieldProblem(
            b_name, f"{b_name} has {len(b)} values but {a_name} has {len(a)}; give one per {a_name.removesuffix('s')}"
        )


def one_location(point: str | None, point_name: str, branch: str | None, chainage: float | None, what: str) -> None:
    """Check that ``what`` sits either at ``point_name`` (a node or structure) or at a branch and chainage."""
    if branch is not None and chainage is None:
        raise FieldProblem("chainage", f"{what} on a branch needs a chainage (m from the start of the branch)")
    if chainage is not None and branch is None:
        raise FieldProblem("branch", f"{what} with a chainage needs the branch it lies on")
    if point is not None and branch is not None:
        raise FieldProblem(point_name, f"give either {point_name}, or branch and chainage, not both")
    if point is None and branch is None:
        raise FieldProblem(point_name, f"{what} needs a location: {point_name}, or branch and chainage")
