"""The embedded engine behind the model contract: a case, its rainfall-runoff inflows, the Simulator.

:class:`EmbeddedModel` is the :class:`~rivercal.engine.Simulator` of a case (everything it offers stays
available: ``case``, ``compiled``, ``initial_state`` …) plus the declarations of the model contract
(:mod:`rivercal.models.contract`): the settable quantities with units and bounds, the calibration setup
of ``case.toml``, and its state as bytes.

Quantities:

- ``weir:<id>.crest_level`` — crest level of a weir, m AD;
- ``friction:global`` — the friction value of every branch that inherits the case's friction (unit of
  the case's friction type, e.g. k_s in m^(1/3)/s), present when some branch inherits it;
- ``friction:branch:<id>`` — the friction value of one branch (unit of its friction type);
- ``friction:group:<id>`` — the value of a friction group (``[[friction_groups]]``, unit of its law);
- ``friction:scale`` — a factor (-) on the conveyance of every channel friction coefficient, present when
  no link uses White-Colebrook friction (a factor on its coefficient does not scale its conveyance);
- ``control:<id>.setpoint`` (m AD, m³/s for a discharge), ``.kp`` (m/m), ``.ki`` (1/s), ``.kd`` (s),
  ``.value:<k>`` (m AD) — the quantities of the case's controllers (:mod:`rivercal.engine.controllers`); a
  weir driven by a controller declares no ``crest_level``.

Friction bounds are the plausible ranges of :data:`rivercal.network.FRICTION_RANGES`.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.case.load import Case, load_case
from rivercal.engine.compile import FRICTION_CODES
from rivercal.engine.simulator import Simulator
from rivercal.engine.state import EngineState
from rivercal.hydrology.catchments import catchment_forcing
from rivercal.models.contract import CalibrationSetup, Quantity, utc
from rivercal.network import FRICTION_RANGES, MAX_LEVEL

__all__ = ["EmbeddedModel", "build_model", "load_case_model"]


class EmbeddedModel(Simulator):
    """A case ready to run on the embedded engine, with the model contract's declarations.

    Parameters
    ----------
    case
        A loaded case.
    forcing
        Replacement series for boundaries and laterals (see :class:`~rivercal.engine.Simulator`).

    Examples
    --------
    >>> from rivercal.models import build_model
    >>> from rivercal.case import load_case
    >>> model = build_model(load_case("synthetic"))
    >>> model.quantities["weir:W1.crest_level"].unit
    'm AD'
    """

    def __init__(self, case: Case, forcing: Mapping[str, pd.Series] | None = None):
        super().__init__(case, forcing=forcing)

    @property
    def name(self) -> str:
        """The case's name."""
        return self.case.name

    @property
    def output_interval(self) -> float:
        """Default interval of the station series, s."""
        return float(self.settings.output_interval)

    @property
    def numerical_noise(self) -> float:
        """The Picard level tolerance of a time step, m.

        An upper bound of the jitter a tiny parameter change causes in the simulated levels.
        """
        return float(self.settings.tolerance)

    @functools.cached_property
    def quantities(self) -> dict[str, Quantity]:
        """The settable quantities (module docstring)."""
        c = self.compiled
        controlled = {spec.weir for spec in self.controls.specs} if self.controls else set()
        out = {f"weir:{w}.crest_level": Quantity(f"weir:{w}.crest_level", "m AD", -MAX_LEVEL, MAX_LEVEL,
                                                  f"crest level of weir {w}")
               for w in c.weir_ids if w not in controlled}
        names = {code: name for name, code in FRICTION_CODES.items()}
        if c.branch_inherits:
            low, high, unit = FRICTION_RANGES[self.case.spec.friction.type]
            out["friction:global"] = Quantity("friction:global", unit, low, high,
                                              f"{self.case.spec.friction.type} friction of the branches that "
                                              "inherit the case's friction")
        for i, b in enumerate(c.branch_ids):
            kind = names[int(c.arrays.fr_type[i])]
            low, high, unit = FRICTION_RANGES[kind]
            out[f"friction:branch:{b}"] = Quantity(f"friction:branch:{b}", unit, low, high,
                                                   f"{kind} friction of branch {b}")
        for i, key in enumerate(c.friction_slots):
            if key[0] == "group" and len(key) == 2:
                kind = names[int(c.arrays.fr_type[i])]
                low, high, unit = FRICTION_RANGES[kind]
                out[f"friction:group:{key[1]}"] = Quantity(f"friction:group:{key[1]}", unit, low, high,
                                                           f"{kind} friction of friction group {key[1]}")
        used = set(np.unique(c.arrays.lk_fric).tolist())  # the friction slots some link uses
        if all(names[int(code)] != "white-colebrook" for i, code in enumerate(c.arrays.fr_type) if i in used):
            out["friction:scale"] = Quantity("friction:scale", "-", 0.05, 20.0,
                                             "factor on the conveyance of every channel friction coefficient")
        for name, (unit, low, high, text) in (self.controls.describe() if self.controls else {}).items():
            out[name] = Quantity(name, unit, low, high, text)
        return out

    @functools.cached_property
    def calibration(self) -> CalibrationSetup:
        """Parameters, windows and optimiser defaults of ``case.toml``."""
        spec = self.case.spec
        return CalibrationSetup(parameters=tuple(spec.parameters),
                                windows={w.name: (utc(w.start), utc(w.end)) for w in spec.windows},
                                algorithm=spec.calibration.algorithm, options=dict(spec.calibration.options))

    # -- state ------------------------------------------------------------------------------------

    def start_state(self, start: pd.Timestamp | None = None,
                    parameters: Mapping[str, float] | None = None) -> EngineState:
        """The state a cold-started run begins from at ``start``.

        The case's initial state, then its spin-up with the forcing held at its ``start`` value and the
        given quantities (what :meth:`simulate` does without a state).
        """
        start = self.start if start is None else utc(start)
        crest, fric = self.parameter_arrays(parameters)
        state = self.initial_state(start)
        hours = self.case.spec.initial.spinup
        if hours > 0:
            n = max(1, round(hours * 3600.0 / self.dt))
            spin = self.forcing_matrix(start, n, constant=True)
            self._run(state, crest, fric, spin, n, False, start - pd.Timedelta(seconds=n * self.dt), phase="spin-up",
                      control=self.control_values(parameters))
        state.time = start
        return state

    @property
    def state_format(self) -> str:
        """Format tag of :meth:`save_state`."""
        return EngineState.BYTES_FORMAT

    def save_state(self, state: EngineState) -> bytes:
        """The engine state as bytes (:meth:`EngineState.to_bytes`, no pickle)."""
        return state.to_bytes()

    def load_state(self, data: bytes, fmt: str) -> EngineState:
        """An engine state of this network from :meth:`save_state` bytes.

        Raises
        ------
        ValueError
            For another format, bytes that are no engine state, or a state of another grid.
        """
        state = EngineState.from_bytes(data, fmt)
        if state.signature != (self.compiled.n_hpoints, self.compiled.n_links):
            raise ValueError(f"the state belongs to another grid ({state.signature[0]} points, "
                             f"{state.signature[1]} links; case {self.name!r} has {self.compiled.n_hpoints} and "
                             f"{self.compiled.n_links})")
        return state


def build_model(case: Case) -> EmbeddedModel:
    """The embedded model of ``case``; its catchment-fed laterals carry the rainfall-runoff inflow.

    A bad ``[runoff]`` table or meteo file fails here, when the model is built, before any run.
    """
    return EmbeddedModel(case, forcing=catchment_forcing(case))


def load_case_model(source: str | Path) -> EmbeddedModel:
    """Load a case (folder or packaged name) and build its embedded model."""
    return build_model(load_case(source))
