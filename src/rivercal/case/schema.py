"""Schema of ``case.toml``: the network plus the simulated period, engine settings and initial state.

``rivercal case schema`` prints the JSON Schema of :class:`CaseFile`; ``docs/case-format.md``
documents every field with its unit.
"""

from __future__ import annotations

from datetime import UTC, datetime

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from rivercal.network.schema import Network

__all__ = ["CaseFile", "CaseMeta", "EngineSettings", "InitialConditions"]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class CaseMeta(_Model):
    """Identity and simulated period of a case.

    Attributes
    ----------
    name
        Short name of the case.
    description
        Free text.
    start, end
        Simulated period (UTC; a time without offset is read as UTC).
    """

    name: str = Field(min_length=1)
    description: str = ""
    start: datetime
    end: datetime

    @field_validator("start", "end")
    @classmethod
    def _utc(cls, value: datetime) -> datetime:
        if value.tzinfo is None:
            return value.replace(tzinfo=UTC)
        return value.astimezone(UTC)

    @model_validator(mode="after")
    def _ordered(self) -> CaseMeta:
        if self.end <= self.start:
            raise ValueError(f"end {self.end.isoformat()} is not after start {self.start.isoformat()}")
        return self


class EngineSettings(_Model):
    """Numerical settings of the embedded engine.

    Attributes
    ----------
    dt
        Time step, s.
    theta
        Implicitness of the continuity flux, in [0.5, 1] (1: fully implicit).
    output_interval
        Interval of the station series, s (a multiple of ``dt``).
    max_iterations
        Picard iterations per step for structures and non-linear storage (at least 1).
    tolerance
        Level change below which the iterations of a step stop, m.
    min_depth
        Upwind depth below which a channel link carries no flow, m.
    min_storage_area
        Storage area added at every calculation point so that no point has zero storage, m².
    structure_length
        Length of the short channel segment that holds a structure, m; the calculation points at
        its ends give the levels up- and downstream of the structure.
    max_velocity
        Velocity above which the run is declared diverged, m/s.
    """

    dt: float = Field(default=60.0, gt=0, le=3600)
    theta: float = Field(default=1.0, ge=0.5, le=1.0)
    output_interval: float = Field(default=3600.0, gt=0)
    max_iterations: int = Field(default=2, ge=1, le=50)
    tolerance: float = Field(default=1e-5, gt=0)
    min_depth: float = Field(default=1e-3, gt=0)
    min_storage_area: float = Field(default=1.0, gt=0)
    structure_length: float = Field(default=10.0, gt=0)
    max_velocity: float = Field(default=20.0, gt=0)

    @model_validator(mode="after")
    def _interval(self) -> EngineSettings:
        ratio = self.output_interval / self.dt
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(f"output_interval {self.output_interval} s is not a multiple of dt {self.dt} s")
        return self


class InitialConditions(_Model):
    """Cold-start state.

    Attributes
    ----------
    depth
        Initial depth above the bed at every calculation point, m.
    level
        Optional minimum initial level everywhere, m AD (the level is max(bed + depth, level)).
    spinup
        Duration before ``start`` that is simulated with the forcing held at its start value, h,
        so that a cold start reaches a realistic state; the spin-up is not part of the output.
    """

    depth: float = Field(default=0.5, ge=0)
    level: float | None = None
    spinup: float = Field(default=0.0, ge=0)


class CaseFile(Network):
    """The whole ``case.toml``: ``[case]``, ``[engine]``, ``[initial]`` and the network tables."""

    case: CaseMeta
    engine: EngineSettings = EngineSettings()
    initial: InitialConditions = InitialConditions()

    @model_validator(mode="after")
    def _period_fits_output(self) -> CaseFile:
        seconds = (self.case.end - self.case.start).total_seconds()
        ratio = seconds / self.engine.output_interval
        if abs(ratio - round(ratio)) > 1e-9:
            raise ValueError(
                f"case: the period ({seconds:.0f} s) is not a multiple of engine.output_interval "
                f"({self.engine.output_interval:.0f} s)"
            )
        return self

    def network(self) -> Network:
        """The network part of the case as a plain :class:`~rivercal.network.Network`."""
        fields = set(Network.model_fields)
        return Network.model_validate(self.model_dump(include=fields, by_alias=True))
