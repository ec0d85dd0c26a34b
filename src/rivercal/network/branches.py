"""Branches (channel reaches between two nodes) and the cross-sections placed along them."""

from __future__ import annotations

import itertools

import numpy as np
from pydantic import Field, model_validator

from rivercal.errors import FieldProblem
from rivercal.network._base import Identifier, Level, NetworkModel, Real, num, same_length, strictly_increasing
from rivercal.network.friction import Friction

__all__ = ["MAX_POINTS_PER_BRANCH", "Branch", "CrossSection", "InitialLevels"]

#: Most calculation points one branch may get (length / dx); more is a unit mistake, not a model.
MAX_POINTS_PER_BRANCH = 100_000


class CrossSection(NetworkModel):
    """A cross-section placed on a branch.

    Attributes
    ----------
    chainage
        Distance from the start of the branch, m.
    profile
        Id of a profile in ``profiles``.
    bed_level
        Level of the lowest point of the profile, m AD. Bed levels are interpolated linearly
        between cross-sections; each calculation point takes the shape of the nearest one.
    """

    chainage: Real = Field(ge=0, description="distance from the start of the branch, m")
    profile: Identifier = Field(description="id of a profile in [[profiles]]")
    bed_level: Level = Field(description="level of the lowest point of the profile, m AD")


class InitialLevels(NetworkModel):
    """Initial water levels along a branch (a cold start from a surveyed or computed water line).

    Attributes
    ----------
    chainages
        Chainages, m from the start of the branch, strictly increasing.
    levels
        Water level at each chainage, m AD; linear between the chainages and constant beyond the first and
        the last. A level below the bed leaves the point dry.
    """

    chainages: list[Real] = Field(min_length=1, description="chainages, m from the start of the branch, increasing")
    levels: list[Level] = Field(min_length=1, description="initial water level at each chainage, m AD")

    @model_validator(mode="after")
    def _check(self) -> InitialLevels:
        same_length(self.chainages, "chainages", self.levels, "levels")
        strictly_increasing(self.chainages, "chainages", "m")
        if self.chainages[0] < 0:
            raise FieldProblem("chainages[0]", f"chainages are m from the start of the branch, got "
                                               f"{num(self.chainages[0])} m")
        return self

    def level_at(self, chainage: np.ndarray | float) -> np.ndarray:
        """Initial level at chainages (m), m AD."""
        return np.interp(chainage, self.chainages, self.levels)


class Branch(NetworkModel):
    """A channel reach between two connection nodes.

    Attributes
    ----------
    from_node, to_node
        Node ids at chainage 0 and at the end; positive flow runs from ``from_node`` to ``to_node``.
    length
        Length along the axis, m.
    dx
        Target spacing of calculation points, m (default 100 m).
    friction
        Friction of this branch; when absent the branch inherits the case's global friction.
    cross_sections
        At least one cross-section, ordered by chainage.
    geometry
        Optional polyline ``[[x, y], ...]`` in m for plots.
    points
        Optional chainages of the calculation points, m, from 0 to ``length`` (as a D-Flow FM grid
        gives them). Then ``dx`` is not used, and a structure occupies the stretch between the two
        points around it instead of a segment of ``engine.structure_length``.
    order
        Optional order number (D-Flow FM's ``branchOrder``, SOBEK 3's ``order``). With
        ``engine.cross_sections = "interpolated"``, cross-sections are interpolated across a connection node
        into the next branch of the same positive order, as D-Flow FM does, instead of being held constant from
        the last cross-section to the branch end.
    initial_levels
        Optional initial water levels along the branch (cold start), instead of the case's ``[initial]``.
    """

    id: Identifier = Field(description="branch id (its own friction is the parameter friction:branch:<id>)")
    from_node: Identifier = Field(description="node at chainage 0 (positive flow runs from here)")
    to_node: Identifier = Field(description="node at the end of the branch (chainage = length)")
    length: Real = Field(ge=0.1, le=1.0e7, description="length along the channel axis, m")
    dx: Real = Field(default=100.0, gt=0, description="target spacing of calculation points, m")
    friction: Friction | None = Field(
        default=None, description="friction of this branch (default: the global friction)"
    )
    cross_sections: list[CrossSection] = Field(
        min_length=1, description="cross-sections ordered by chainage (at least one)"
    )
    geometry: list[tuple[Real, Real]] | None = Field(
        default=None, min_length=2, description="polyline [[x, y], ...] of the channel axis, m (optional, for plots)"
    )
    points: list[Real] | None = Field(
        default=None, min_length=2,
        description="chainages of the calculation points, m, from 0 to length (optional; then dx is not used)",
    )
    order: int | None = Field(
        default=None, ge=-1000000, le=1000000,
        description="order number: cross-sections are interpolated across a node into the next branch of the same "
                    "positive order (D-Flow FM branchOrder; with cross_sections = 'interpolated')",
    )
    initial_levels: InitialLevels | None = Field(
        default=None, description="initial water levels along the branch, m AD (cold start; instead of [initial])"
    )

    @model_validator(mode="after")
    def _check_sections(self) -> Branch:
        if self.from_node == self.to_node:
            raise FieldProblem(
                "to_node", f"from_node and to_node are the same node {self.from_node!r}; a branch joins two nodes"
            )
        chainages = [cs.chainage for cs in self.cross_sections]
        for i, (a, b) in enumerate(itertools.pairwise(chainages), start=1):
            if not b > a:
                raise FieldProblem(
                    f"cross_sections[{i}].chainage",
                    f"cross-sections must be ordered by increasing chainage, but {num(b)} m follows {num(a)} m",
                )
        if chainages[-1] > self.length:
            raise FieldProblem(
                f"cross_sections[{len(chainages) - 1}].chainage",
                f"cross-section at chainage {num(chainages[-1])} m lies beyond the end of the branch "
                f"({num(self.length)} m long)",
            )
        if self.points is not None:
            self._check_points()
            return self
        points = self.length / self.dx
        if points > MAX_POINTS_PER_BRANCH:
            raise FieldProblem(
                "dx",
                f"dx = {num(self.dx)} m on a branch of {num(self.length)} m gives {points:,.0f} calculation points "
                f"(at most {MAX_POINTS_PER_BRANCH:,}); dx and length are in metres",
            )
        return self

    def _check_points(self) -> None:
        pts = self.points
        tol = 1e-6 * max(1.0, self.length)
        if abs(pts[0]) > tol:
            raise FieldProblem("points[0]", f"the first calculation point must be at chainage 0, got {num(pts[0])} m")
        if abs(pts[-1] - self.length) > tol:
            raise FieldProblem(f"points[{len(pts) - 1}]", f"the last calculation point must be at the end of the "
                                                          f"branch ({num(self.length)} m), got {num(pts[-1])} m")
        for i, (a, b) in enumerate(itertools.pairwise(pts), start=1):
            if not b > a:
                raise FieldProblem(f"points[{i}]", f"calculation points must increase strictly, but {num(b)} m "
                                                   f"follows {num(a)} m")
        if len(pts) > MAX_POINTS_PER_BRANCH:
            raise FieldProblem("points", f"{len(pts):,} calculation points (at most {MAX_POINTS_PER_BRANCH:,})")

    def bed_level_at(self, chainage: float) -> float:
        """Bed level at a chainage, m AD (linear between cross-sections, constant beyond)."""
        ch = [cs.chainage for cs in self.cross_sections]
        zb = [cs.bed_level for cs in self.cross_sections]
        return float(np.interp(chainage, ch, zb))

