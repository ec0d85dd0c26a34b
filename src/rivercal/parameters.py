"""Calibration parameters: names at the edges, model quantities and flat vectors inside.

A :class:`Parameter` is one number the calibration estimates. It has physical bounds (thesis Eq. 2-7;
always in physical units, so a restart from new initial values keeps its range — a known OpenDA defect otherwise),
an initial value, a transform that sets how the optimiser perturbs it, an optional prior standard
deviation (a weak constraint), and targets:

- one or more model quantities that all take the parameter's value; or
- a *cluster* of quantities (usually weir crests), moved by one number. ``cluster_mode = "fraction"``
  (thesis §4-4, "Wc"): a value in [0, 1] that places every target between its own minimum and maximum,
  crest = min + value × (max - min). ``cluster_mode = "shift"``: a change that moves every target from
  its reference value alike, crest = base + value (an operator lowering all weirs by 15 cm is
  value = -0.15 m); the parameter's bounds must keep every target inside its own range.

A target is the name of a quantity that the model declares settable (the model contract,
:mod:`rivercal.models.contract`): ``weir:<id>.crest_level`` (m AD), ``friction:global``, ``friction:branch:<id>``,
``friction:group:<id>`` (in the unit of the friction law) or ``friction:scale`` (a factor on every channel
friction's conveyance) of the embedded engine, ``roughness:factor`` of a SWMM model, a placeholder name of
an external program … This module checks only the form of a name; the calibration problem checks it
against the model it runs.

Transforms (what the optimiser sees, and the first DuD step λ):

- ``offset`` (thesis Eq. 2-8): x = θ, first step θ₀ + λ;
- ``factor`` (Eq. 2-9): x = θ, first step θ₀ + λ θ₀;
- ``ln``: x = ln θ, first step ln θ₀ + λ (multiplicative; needs positive bounds).

:class:`ParameterSet` maps names ↔ positions of the optimiser's vector and parameter values ↔ the
model quantities of the model protocol.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["TARGET_PATTERN", "ClusterTarget", "Parameter", "ParameterSet", "shared_quantity"]

#: The form of a model quantity's name: a letter or _, then letters, digits and ``_ . : - /`` (no spaces,
#: no braces, no quotes), at most 200 characters.
TARGET_PATTERN = r"^[A-Za-z_][A-Za-z0-9_.:/\-]{0,199}$"
Target = Annotated[str, Field(pattern=TARGET_PATTERN)]


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class ClusterTarget(_Model):
    """A member of a cluster parameter (usually a weir crest).

    Attributes
    ----------
    target
        A model quantity, e.g. ``weir:<id>.crest_level``.
    min, max
        The range of this target (a crest: m AD, thesis Table 4-2).
    base
        Reference value from which a ``shift`` cluster moves this target (required there).
    """

    target: Target = Field(description="model quantity, e.g. weir:<id>.crest_level")
    min: float = Field(description="lowest value of this target (a crest level: m AD)")
    max: float = Field(description="highest value of this target (a crest level: m AD)")
    base: float | None = Field(default=None, description="reference value for a shift cluster")

    @model_validator(mode="after")
    def _ordered(self) -> ClusterTarget:
        if not self.max > self.min:
            raise ValueError(f"max {self.max} must be above min {self.min} for {self.target}")
        return self


class Parameter(_Model):
    """One calibration parameter (see the module docstring).

    Attributes
    ----------
    name
        Short name (``FA``, ``W2``, ``Wc``).
    targets
        Model quantities that take the value (or use ``cluster``).
    cluster
        Quantities (weir crests) moved together by the value (see ``cluster_mode``).
    cluster_mode
        ``fraction``: the value in [0, 1] places each target between its min and max; ``shift``: the
        value (m for crests) is added to each target's ``base``.
    min, max
        Physical bounds of the value (a fraction cluster lives in [0, 1]).
    initial
        Initial value.
    transform
        ``offset``, ``factor`` or ``ln``.
    perturbation
        λ, the first DuD step (parameter units for offset, a fraction for factor, ln units for ln).
    prior_std
        Standard deviation of a weak constraint towards ``initial`` (in the optimiser's units), or None.
    unit
        Unit of the value, for reports.
    """

    name: str = Field(pattern=r"^[A-Za-z][A-Za-z0-9_]*$", max_length=32, description="parameter name")
    targets: list[Target] = Field(default_factory=list, description="model quantities that take the value")
    cluster: list[ClusterTarget] = Field(default_factory=list, description="quantities moved together by the value")
    cluster_mode: Literal["fraction", "shift"] = Field(
        default="fraction", description="fraction: value in [0, 1] of each weir's range; shift: m added to each base")
    min: float = Field(description="lower bound, physical units")
    max: float = Field(description="upper bound, physical units")
    initial: float = Field(description="initial value, physical units")
    transform: Literal["offset", "factor", "ln"] = Field(default="offset", description="perturbation transform")
    perturbation: float = Field(gt=0, description="first DuD step λ (see transform)")
    prior_std: float | None = Field(default=None, gt=0, description="weak-constraint standard deviation")
    unit: str = Field(default="", description="unit of the value")

    @model_validator(mode="after")
    def _consistent(self) -> Parameter:
        if bool(self.targets) == bool(self.cluster):
            raise ValueError(f"parameter {self.name!r} needs targets or a cluster (exactly one of them)")
        if not self.max > self.min:
            raise ValueError(f"parameter {self.name!r}: max {self.max} must be above min {self.min}")
        if not self.min <= self.initial <= self.max:
            raise ValueError(f"parameter {self.name!r}: initial {self.initial} lies outside [{self.min}, {self.max}]")
        if self.cluster and self.cluster_mode == "fraction" and (self.min < 0.0 or self.max > 1.0):
            raise ValueError(f"cluster parameter {self.name!r} lives in [0, 1], got [{self.min}, {self.max}]")
        if self.cluster and self.cluster_mode == "shift":
            for c in self.cluster:
                if c.base is None:
                    raise ValueError(f"shift cluster {self.name!r}: {c.target} needs a base crest level")
                if c.base + self.min < c.min - 1e-9 or c.base + self.max > c.max + 1e-9:
                    raise ValueError(f"shift cluster {self.name!r}: bounds [{self.min:g}, {self.max:g}] move "
                                     f"{c.target} from {c.base:g} outside its range [{c.min:g}, {c.max:g}]")
        if self.transform == "ln" and self.min <= 0.0:
            raise ValueError(f"parameter {self.name!r}: the ln transform needs a positive lower bound")
        return self

    # -- optimiser space --------------------------------------------------------------------------

    def to_x(self, value: float) -> float:
        """Optimiser coordinate of a physical value."""
        return math.log(value) if self.transform == "ln" else float(value)

    def from_x(self, x: float) -> float:
        """Physical value of an optimiser coordinate."""
        return math.exp(x) if self.transform == "ln" else float(x)

    def initial_step(self, value: float) -> float:
        """The first DuD perturbation at ``value``, in optimiser units (thesis Eq. 2-8 / 2-9)."""
        if self.transform == "factor":
            return self.perturbation * max(abs(value), 1e-12)
        return self.perturbation

    def quantities(self, value: float) -> dict[str, float]:
        """Model quantities (target → value) for a physical value of this parameter."""
        if self.cluster and self.cluster_mode == "shift":
            return {c.target: c.base + value for c in self.cluster}  # type: ignore[operator]
        if self.cluster:
            return {c.target: c.min + value * (c.max - c.min) for c in self.cluster}
        return dict.fromkeys(self.targets, float(value))


def shared_quantity(parameters: Iterable[Parameter]) -> tuple[str, str, str] | None:
    """The first model quantity that two of ``parameters`` set: (first parameter, second parameter, quantity).

    None when each quantity has one parameter at most (e.g. a weir's crest level and the shift of all
    crests both set that weir's crest).
    """
    owner: dict[str, str] = {}
    for p in parameters:
        for target in p.quantities(p.initial):
            if target in owner:
                return owner[target], p.name, target
            owner[target] = p.name
    return None


class ParameterSet:
    """An ordered set of parameters: the flat vector of the optimiser ↔ names ↔ model quantities.

    Parameters
    ----------
    parameters
        The parameters in vector order; names must be unique and no model quantity may be set by two
        parameters.
    """

    def __init__(self, parameters: Iterable[Parameter]):
        self.parameters: tuple[Parameter, ...] = tuple(parameters)
        names = [p.name for p in self.parameters]
        if len(set(names)) != len(names):
            raise ValueError(f"duplicate parameter names in {names}")
        shared = shared_quantity(self.parameters)
        if shared is not None:
            raise ValueError(f"{shared[2]} is set by both {shared[0]!r} and {shared[1]!r}")

    def __len__(self) -> int:
        return len(self.parameters)

    def __iter__(self):
        return iter(self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(f"no parameter {name!r} (have: {', '.join(self.names)})")

    @property
    def names(self) -> list[str]:
        """Parameter names in vector order."""
        return [p.name for p in self.parameters]

    def subset(self, names: Sequence[str]) -> ParameterSet:
        """The parameters with these names, in this order."""
        return ParameterSet(self[n] for n in names)

    def with_initial(self, values: Mapping[str, float]) -> ParameterSet:
        """The same parameters with new initial values (bounds unchanged: they are physical)."""
        return ParameterSet(p.model_copy(update={"initial": float(values[p.name])}) if p.name in values else p
                            for p in self.parameters)

    # -- vectors -----------------------------------------------------------------------------------

    def values(self, x: np.ndarray) -> dict[str, float]:
        """Physical values by name of an optimiser vector."""
        return {p.name: p.from_x(float(v)) for p, v in zip(self.parameters, np.asarray(x, dtype=float), strict=True)}

    def to_x(self, values: Mapping[str, float] | None = None) -> np.ndarray:
        """Optimiser vector of physical values by name (default: the initial values)."""
        values = values or {}
        return np.array([p.to_x(values.get(p.name, p.initial)) for p in self.parameters])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds of the optimiser vector."""
        return (np.array([p.to_x(p.min) for p in self.parameters]), np.array([p.to_x(p.max) for p in self.parameters]))

    def initial_steps(self, values: Mapping[str, float] | None = None) -> np.ndarray:
        """The first DuD perturbation of each parameter at the given (default: initial) values."""
        values = values or {}
        return np.array([p.initial_step(values.get(p.name, p.initial)) for p in self.parameters])

    def prior_std(self) -> np.ndarray | None:
        """Weak-constraint standard deviations (optimiser units), or None when no parameter has one."""
        if all(p.prior_std is None for p in self.parameters):
            return None
        return np.array([p.prior_std if p.prior_std is not None else np.inf for p in self.parameters])

    def quantities(self, values: Mapping[str, float]) -> dict[str, float]:
        """Model quantities (target → value) for physical values by name; missing names take their initial."""
        out: dict[str, float] = {}
        for p in self.parameters:
            out.update(p.quantities(values.get(p.name, p.initial)))
        return out

    # -- views ---------------------------------------------------------------------------------------

    def __repr__(self) -> str:
        items = ", ".join(f"{p.name}={p.initial:g} in [{p.min:g}, {p.max:g}]{' ' + p.unit if p.unit else ''}"
                          for p in self.parameters)
        return f"ParameterSet({items})"

    def to_frame(self) -> pd.DataFrame:
        """The parameters as a table, one row per name (values in the parameters' units).

        Columns ``initial``, ``min``, ``max``, ``unit``, ``transform``, ``perturbation``, ``prior_std`` and
        ``targets`` (the model quantities it sets, comma-separated).

        Examples
        --------
        >>> p = Parameter(name="FA", targets=["friction:global"], min=8, max=40, initial=16, perturbation=2,
        ...               unit="m^(1/3)/s")
        >>> ParameterSet([p]).to_frame()[["initial", "min", "max", "unit"]]
              initial  min   max       unit
        name
        FA       16.0  8.0  40.0  m^(1/3)/s
        """
        import pandas as pd

        rows = [{"name": p.name, "initial": p.initial, "min": p.min, "max": p.max, "unit": p.unit,
                 "transform": p.transform, "perturbation": p.perturbation, "prior_std": p.prior_std,
                 "targets": ", ".join(p.quantities(p.initial))} for p in self.parameters]
        columns = ["name", "initial", "min", "max", "unit", "transform", "perturbation", "prior_std", "targets"]
        return pd.DataFrame(rows, columns=columns).set_index("name")
