"""Observation stations: at a structure (levels either side, discharge) or at a chainage on a branch."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import Identifier, NetworkModel, Real, one_location

__all__ = ["QUANTITIES_AT_STRUCTURE", "QUANTITIES_ON_BRANCH", "Station", "StationQuantity"]

StationQuantity = Literal["h", "h_up", "h_down", "Q"]
QUANTITIES_AT_STRUCTURE = ("h_up", "h_down", "Q")
QUANTITIES_ON_BRANCH = ("h", "Q")


class Station(NetworkModel):
    """An observation station.

    A station either sits at a structure (quantities ``h_up``, ``h_down``, ``Q``) or at a
    chainage on a branch (quantities ``h``, ``Q``). Its simulated series are named
    ``"<id>.<quantity>"``, so a station id must not contain a dot.

    Attributes
    ----------
    structure
        Id of a weir, culvert or pump.
    branch, chainage
        A location on a branch, m.
    quantities
        Observed quantities (default ``h_up, h_down`` at a structure, ``h`` on a branch).
    """

    id: Identifier = Field(description="station id, the prefix of its series names '<id>.<quantity>' (no '.')")
    structure: Identifier | None = Field(default=None, description="id of a weir, culvert or pump")
    branch: Identifier | None = Field(default=None, description="branch of a station that is not at a structure")
    chainage: Real | None = Field(default=None, ge=0, description="location on the branch, m from its start")
    quantities: list[StationQuantity] | None = Field(
        default=None,
        min_length=1,
        description="observed quantities: 'h_up', 'h_down', 'Q' at a structure (default h_up, h_down); "
        "'h', 'Q' on a branch (default h). Levels in m AD, discharges in m³/s",
    )

    @model_validator(mode="after")
    def _location(self) -> Station:
        if "." in self.id:
            raise FieldProblem(
                "id", f"station id {self.id!r} contains a '.'; series are named '<station>.<quantity>', so it cannot"
            )
        one_location(self.structure, "structure", self.branch, self.chainage, "a station")
        allowed = QUANTITIES_AT_STRUCTURE if self.structure is not None else QUANTITIES_ON_BRANCH
        seen: set[str] = set()
        for i, q in enumerate(self.quantities or []):
            if q not in allowed:
                if self.structure is not None:
                    reason = (f"quantity {q!r} does not exist at a structure; use 'h_up' and 'h_down' for the levels "
                              "either side of it, or 'Q'")
                else:
                    reason = (f"quantity {q!r} exists only at a structure; a station on a branch measures 'h' or "
                              "'Q' (use structure = <id> for levels either side of a structure)")
                raise FieldProblem(f"quantities[{i}]", reason)
            if q in seen:
                raise FieldProblem(f"quantities[{i}]", f"quantity {q!r} is listed twice")
            seen.add(q)
        return self

    @property
    def observables(self) -> list[str]:
        """Names ``"<station>.<quantity>"`` of the series this station produces."""
        default = ["h_up", "h_down"] if self.structure is not None else ["h"]
        return [f"{self.id}.{q}" for q in (self.quantities or default)]


