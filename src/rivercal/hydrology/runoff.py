r"""Conceptual lowland rainfall-runoff model of the Wageningen family (WALRUS structure).

The thesis (§3-1-2) computes its lateral inflows with the Wageningen model (Stricker & Warmerdam
1982): a conceptual lowland model with capillary rise and a division between fast and slow flow that
depends on the wetness of the groundwater reservoir. This module implements its successor from the
same group, WALRUS (Brauer et al. 2014a), from the equations published in that paper (no code
was taken from the GPL WALRUS R package). WALRUS keeps both lowland features: the vadose zone and
the groundwater form one coupled reservoir whose storage deficit is refilled from the groundwater
(the role of capillary rise), and the share of rain that takes the fast route grows with the
wetness of that reservoir.

Simplifications with respect to the published model: no seepage or surface water supply
(:math:`f_{XG} = f_{XS} = 0`), no snow or interception, a fixed stage-discharge relation without a
minimum level (:math:`h_{S,min} = 0`), no instantaneous redistribution during large-scale ponding,
and the fluxes written per unit land area (land) or catchment area (discharge) as below.

Reservoirs and states
---------------------
The catchment has a land part (area fraction :math:`1-a_S`) and a surface water part (channels,
ditches; fraction :math:`a_S`).

=========  =========================================================================  ====
state      meaning                                                                    unit
=========  =========================================================================  ====
``d_v``    :math:`d_V`, storage deficit of the coupled vadose-groundwater reservoir   mm
           (water needed to saturate the soil to the surface; < 0 means ponding)
``d_g``    :math:`d_G`, groundwater depth below the surface                           mm
``h_q``    :math:`h_Q`, level of the quickflow reservoir (drains, macropores,         mm
           overland flow)
``h_s``    :math:`h_S`, surface water level above the channel bottom                  mm
=========  =========================================================================  ====

Fluxes (mm/h). Land fluxes are per unit land area, :math:`Q` per unit catchment area:

- Wetness index and division of rain:
  :math:`W = \tfrac12 \cos\!\big(\pi \min(\max(d_V,0),c_W)/c_W\big) + \tfrac12`;
  :math:`P_Q = W P` to the quickflow reservoir, :math:`P_V = (1-W) P` to the soil, and
  :math:`P` falls directly on the surface water.
- Evapotranspiration: :math:`ET_V = \beta(d_V)\,ET_{pot}` from the land with
  :math:`\beta = \tfrac12 + \tfrac12 \,(1-e^{\zeta_1 (d_V-\zeta_2)})/(1+e^{\zeta_1 (d_V-\zeta_2)})`;
  :math:`ET_S = ET_{pot}` from the surface water while :math:`h_S > 0`.
- Groundwater drainage (negative: infiltration from the surface water):
  :math:`f_{GS} = (c_D - d_G - h_S)\,\max(c_D - d_G,\ h_S) / c_G`.
- Quickflow: :math:`f_{QS} = h_Q / c_Q` (a linear reservoir).
- Discharge (stage-discharge relation of the outlet):
  :math:`Q = c_S\,(\max(h_S,0)/c_D)^{x_S}`.
- Equilibrium storage deficit for a hydrostatic profile above the water table with the
  Clapp-Hornberger retention curve :math:`\theta(\psi) = \theta_s (\psi/\psi_{ae})^{-1/b}`:
  :math:`d_{V,eq} = \theta_s\big(d_G - d_G^{1-1/b}\,\psi_{ae}^{1/b}/(1-1/b) - \psi_{ae}/(1-b)\big)`
  for :math:`d_G > \psi_{ae}`, 0 for :math:`0 < d_G \le \psi_{ae}`, and :math:`d_G` for
  :math:`d_G \le 0` (ponding). (Integral of :math:`\theta_s - \theta(d_G - z)` over the profile.)

State equations:

.. math::

    \frac{d d_V}{dt} = -P_V + ET_V + f_{GS}, \qquad
    \frac{d h_Q}{dt} = P_Q - f_{QS}, \qquad
    \frac{d d_G}{dt} = \frac{d_V - d_{V,eq}(d_G)}{c_V},

    \frac{d h_S}{dt} = P - ET_S + \frac{1-a_S}{a_S}\,(f_{GS} + f_{QS}) - \frac{Q}{a_S}.

Catchment totals (mm/h over the whole catchment): precipitation :math:`P`, actual
evapotranspiration :math:`ET_{act} = (1-a_S)\,ET_V + a_S\,ET_S`, discharge :math:`Q` (this is the
*specific discharge* ``q``). Storage relative to a saturated, empty state:
:math:`S = (1-a_S)(h_Q - d_V) + a_S h_S` (mm), so that
:math:`dS/dt = P - ET_{act} - Q` exactly; the numerical scheme below keeps this to round-off.

Numerics
--------
Within each forcing step (constant :math:`P`, :math:`ET_{pot}`) the model takes explicit substeps
(WALRUS also uses a flexible step). A substep is at most the rest of the forcing step, at most
``0.5 / k`` with ``k`` the largest relaxation rate (of :math:`h_S` through :math:`Q` and
:math:`f_{GS}`, and of :math:`d_G` through :math:`\theta_s/c_V`), and small enough that neither
:math:`h_S` nor :math:`d_V` changes by more than ``max_change_mm``. The quickflow reservoir uses
its exact solution over the substep. Every flux is applied as the same volume to the two
reservoirs it connects, and the outflows of the surface water are scaled down when they would
empty it, so the water balance closes to round-off and :math:`h_Q, h_S \ge 0`.

Parameters (defaults for a Brabant sandy lowland catchment)
-----------------------------------------------------------
See :class:`WalrusParameters` and :data:`PARAMETERS` (bounds and units). The four calibration
parameters of WALRUS are :math:`c_W, c_V, c_G, c_Q` (:data:`CALIBRATION_PARAMETERS`); the others
follow from the catchment (channel depth, surface water fraction, soil type).

References
----------
Brauer, C. C., Teuling, A. J., Torfs, P. J. J. F., Uijlenhoet, R. (2014a): The Wageningen Lowland
Runoff Simulator (WALRUS): a lumped rainfall-runoff model for catchments with shallow groundwater.
*Geosci. Model Dev.* 7, 2313-2332, doi:10.5194/gmd-7-2313-2014.

Brauer, C. C., Torfs, P. J. J. F., Teuling, A. J., Uijlenhoet, R. (2014b): The Wageningen Lowland
Runoff Simulator (WALRUS): application to the Hupsel Brook catchment and the Cabauw polder.
*Hydrol. Earth Syst. Sci.* 18, 4007-4028, doi:10.5194/hess-18-4007-2014.

Clapp, R. B., Hornberger, G. M. (1978): Empirical equations for some soil hydraulic properties.
*Water Resour. Res.* 14(4), 601-604.

Stricker, J. N. M., Warmerdam, P. M. M. (1982): Estimation of the water balance in the Upper Regge
catchment with a simple model. In: Hydrological research basins and their use in water resources
planning, Landeshydrologie, Bern, 479-488.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from rivercal.hydrology import _kernels

__all__ = [
    "CALIBRATION_PARAMETERS",
    "PARAMETERS",
    "SOIL_TYPES",
    "ParameterSpec",
    "RunoffResult",
    "WalrusParameters",
    "WalrusState",
    "lateral_inflow",
    "simulate",
    "steady_state",
]

logger = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class ParameterSpec:
    """Name, calibration bounds (physical space) and unit of one model parameter.

    Attributes
    ----------
    name
        Field name in :class:`WalrusParameters`.
    lower, upper
        Bounds for calibration, in ``unit``.
    unit
        Physical unit.
    description
        What the parameter means.
    log_scale
        True when the parameter spans orders of magnitude (search it in log space).
    """

    name: str
    lower: float
    upper: float
    unit: str
    description: str
    log_scale: bool = False


#: Every model parameter with calibration bounds and unit, in the order of :class:`WalrusParameters`.
PARAMETERS: tuple[ParameterSpec, ...] = (
    ParameterSpec("c_w", 20.0, 1000.0, "mm", "wetness index parameter: deficit above which all rain goes to the soil"),
    ParameterSpec("c_v", 0.1, 200.0, "h", "vadose zone relaxation time (groundwater follows the deficit)", True),
    ParameterSpec("c_g", 1e5, 1e9, "mm h", "groundwater reservoir constant (drainage resistance)", True),
    ParameterSpec("c_q", 0.5, 500.0, "h", "quickflow reservoir constant (mean residence time)", True),
    ParameterSpec("c_s", 0.1, 100.0, "mm/h", "bankfull discharge (discharge when h_s = c_d)", True),
    ParameterSpec("c_d", 300.0, 5000.0, "mm", "channel depth"),
    ParameterSpec("a_s", 0.001, 0.2, "-", "surface water area fraction", True),
    ParameterSpec("x_s", 1.0, 3.0, "-", "stage-discharge exponent"),
    ParameterSpec("b", 2.0, 15.0, "-", "Clapp-Hornberger pore-size distribution exponent"),
    ParameterSpec("psi_ae", 10.0, 1000.0, "mm", "air-entry pressure head", True),
    ParameterSpec("theta_s", 0.2, 0.6, "-", "porosity (saturated volumetric water content)"),
    ParameterSpec("zeta1", 0.002, 0.2, "1/mm", "steepness of the evapotranspiration reduction", True),
    ParameterSpec("zeta2", 50.0, 2000.0, "mm", "storage deficit at which evapotranspiration is halved"),
)

#: The four parameters WALRUS leaves for calibration (Brauer et al. 2014a).
CALIBRATION_PARAMETERS: tuple[str, ...] = ("c_w", "c_v", "c_g", "c_q")

#: Clapp & Hornberger (1978, Table 2) soil parameters: ``b`` (-), ``psi_ae`` (mm), ``theta_s`` (-).
SOIL_TYPES: dict[str, tuple[float, float, float]] = {
    "sand": (4.05, 121.0, 0.395),
    "loamy_sand": (4.38, 90.0, 0.410),
    "sandy_loam": (4.90, 218.0, 0.435),
    "silt_loam": (5.30, 786.0, 0.485),
    "loam": (5.39, 478.0, 0.451),
    "sandy_clay_loam": (7.12, 299.0, 0.420),
    "silty_clay_loam": (7.75, 356.0, 0.477),
    "clay_loam": (8.52, 630.0, 0.476),
    "sandy_clay": (10.4, 153.0, 0.426),
    "silty_clay": (10.4, 490.0, 0.492),
    "clay": (11.4, 405.0, 0.482),
}


@dataclass(frozen=True, slots=True)
class WalrusParameters:
    """Parameters of the rainfall-runoff model (equations in the module docstring).

    The defaults describe a small sandy lowland catchment in Noord-Brabant. They are a priori
    values, not calibrated (neither for De Dommel nor for Hupsel): the four calibration parameters
    and the channel geometry (1.5 m deep ditches and brooks covering 1 % of the area) are of the
    order of magnitude WALRUS applications use for the Hupsel Brook, a sandy lowland catchment in
    the east of the Netherlands (Brauer et al. 2014b); the soil is loamy sand, typical of the
    Brabant cover sands ("dekzand"; Clapp & Hornberger 1978); the evapotranspiration reduction
    (half at a deficit of 400 mm) is the WALRUS default.

    Attributes
    ----------
    c_w
        Wetness index parameter :math:`c_W` (mm). Default 200.
    c_v
        Vadose zone relaxation time :math:`c_V` (h). Default 4.
    c_g
        Groundwater reservoir constant :math:`c_G` (mm h). Default 5e6.
    c_q
        Quickflow reservoir constant :math:`c_Q` (h). Default 10.
    c_s
        Bankfull discharge :math:`c_S` (mm/h). Default 4.
    c_d
        Channel depth :math:`c_D` (mm). Default 1500.
    a_s
        Surface water area fraction :math:`a_S` (-). Default 0.01.
    x_s
        Stage-discharge exponent :math:`x_S` (-). Default 1.5.
    b
        Clapp-Hornberger exponent (-). Default 4.38 (loamy sand).
    psi_ae
        Air-entry pressure head (mm). Default 90 (loamy sand).
    theta_s
        Porosity (-). Default 0.41 (loamy sand).
    zeta1
        Steepness of the evapotranspiration reduction (1/mm). Default 0.02.
    zeta2
        Storage deficit at which evapotranspiration is halved (mm). Default 400.

    Examples
    --------
    >>> p = WalrusParameters().replace(c_w=150.0)
    >>> p.to_vector(("c_w", "c_q"))
    array([150.,  10.])
    >>> WalrusParameters.from_vector([120.0, 20.0], ("c_w", "c_q")).c_q
    20.0
    """

    c_w: float = 200.0
    c_v: float = 4.0
    c_g: float = 5.0e6
    c_q: float = 10.0
    c_s: float = 4.0
    c_d: float = 1500.0
    a_s: float = 0.01
    x_s: float = 1.5
    b: float = 4.38
    psi_ae: float = 90.0
    theta_s: float = 0.41
    zeta1: float = 0.02
    zeta2: float = 400.0

    def __post_init__(self) -> None:
        for spec in PARAMETERS:
            value = getattr(self, spec.name)
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise ValueError(f"parameter {spec.name} must be a finite number, got {value!r}")
            if value <= 0.0:
                raise ValueError(f"parameter {spec.name} must be positive ({spec.unit}), got {value}")
        if not self.a_s < 1.0:
            raise ValueError(f"parameter a_s (surface water fraction, -) must be below 1, got {self.a_s}")
        if not self.theta_s < 1.0:
            raise ValueError(f"parameter theta_s (porosity, -) must be below 1, got {self.theta_s}")
        if not self.b > 1.0:
            raise ValueError(f"parameter b (Clapp-Hornberger exponent, -) must exceed 1, got {self.b}")

    def replace(self, **changes: float) -> WalrusParameters:
        """A copy with some parameters changed (unknown names raise ``TypeError``)."""
        unknown = set(changes) - set(self.names())
        if unknown:
            raise TypeError(f"unknown parameter(s) {sorted(unknown)}; known: {list(self.names())}")
        return dataclasses.replace(self, **{k: float(v) for k, v in changes.items()})

    @staticmethod
    def names() -> tuple[str, ...]:
        """All parameter names, in field order."""
        return tuple(spec.name for spec in PARAMETERS)

    @staticmethod
    def spec(name: str) -> ParameterSpec:
        """The :class:`ParameterSpec` (bounds, unit) of one parameter."""
        for spec in PARAMETERS:
            if spec.name == name:
                return spec
        raise KeyError(f"unknown parameter {name!r}; known: {[s.name for s in PARAMETERS]}")

    @classmethod
    def bounds(cls, names: Sequence[str] = CALIBRATION_PARAMETERS) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper calibration bounds of ``names`` (physical units)."""
        specs = [cls.spec(n) for n in names]
        return np.array([s.lower for s in specs]), np.array([s.upper for s in specs])

    def to_vector(self, names: Sequence[str] = CALIBRATION_PARAMETERS) -> np.ndarray:
        """The values of ``names`` as a float array."""
        return np.array([float(getattr(self, n)) for n in names])

    @classmethod
    def from_vector(
        cls, x: ArrayLike, names: Sequence[str] = CALIBRATION_PARAMETERS, base: WalrusParameters | None = None
    ) -> WalrusParameters:
        """Parameters with ``names`` set from ``x`` and the rest from ``base`` (default: the defaults)."""
        x = np.asarray(x, dtype=float).ravel()
        if x.size != len(names):
            raise ValueError(f"{x.size} values for {len(names)} names {tuple(names)}")
        return (base or cls()).replace(**dict(zip(names, x.tolist(), strict=True)))

    @classmethod
    def for_soil(cls, soil: str, **changes: float) -> WalrusParameters:
        """Defaults with the soil parameters of a Clapp-Hornberger soil class (:data:`SOIL_TYPES`)."""
        if soil not in SOIL_TYPES:
            raise KeyError(f"unknown soil type {soil!r}; known: {sorted(SOIL_TYPES)}")
        b, psi_ae, theta_s = SOIL_TYPES[soil]
        return cls(b=b, psi_ae=psi_ae, theta_s=theta_s).replace(**changes)

    def as_dict(self) -> dict[str, float]:
        """Name → value."""
        return {n: float(getattr(self, n)) for n in self.names()}

    def _vector(self, max_change_mm: float, min_substep_h: float) -> np.ndarray:
        par = np.empty(_kernels.NPAR)
        par[:13] = self.to_vector(self.names())
        par[13] = max_change_mm
        par[14] = min_substep_h
        return par


@dataclass(frozen=True, slots=True)
class WalrusState:
    """Model state (all mm).

    Attributes
    ----------
    d_v
        Storage deficit of the vadose-groundwater reservoir (mm; negative = ponding).
    d_g
        Groundwater depth below the surface (mm).
    h_q
        Quickflow reservoir level (mm, >= 0).
    h_s
        Surface water level above the channel bottom (mm, >= 0).
    """

    d_v: float
    d_g: float
    h_q: float = 0.0
    h_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("d_v", "d_g", "h_q", "h_s"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"state {name} must be finite, got {getattr(self, name)}")
        if self.h_q < 0.0 or self.h_s < 0.0:
            raise ValueError(f"h_q and h_s must be >= 0 (mm), got {self.h_q}, {self.h_s}")

    def storage(self, params: WalrusParameters) -> float:
        """Water stored (mm over the catchment) relative to a saturated, empty state: (1-a_s)(h_q - d_v) + a_s h_s."""
        return (1.0 - params.a_s) * (self.h_q - self.d_v) + params.a_s * self.h_s

    def _array(self) -> np.ndarray:
        return np.array([self.d_v, self.d_g, self.h_q, self.h_s], dtype=float)


def steady_state(params: WalrusParameters, q_mm_h: float) -> WalrusState:
    """Dry-weather state that discharges ``q_mm_h`` from groundwater alone.

    The surface water level satisfies :math:`Q(h_S) = q`, the groundwater depth makes the drainage
    :math:`(1-a_S) f_{GS} = q`, the vadose zone is in equilibrium with the groundwater
    (:math:`d_V = d_{V,eq}(d_G)`) and the quickflow reservoir is empty.

    Parameters
    ----------
    params
        Model parameters.
    q_mm_h
        Dry-weather specific discharge (mm/h), > 0.

    Returns
    -------
    WalrusState
        The initial state.
    """
    if not (math.isfinite(q_mm_h) and q_mm_h > 0.0):
        raise ValueError(f"q_mm_h must be a positive discharge (mm/h), got {q_mm_h}")
    h_s = params.c_d * (q_mm_h / params.c_s) ** (1.0 / params.x_s)
    drive = q_mm_h * params.c_g / (1.0 - params.a_s)
    depth = 0.5 * (h_s + math.sqrt(h_s * h_s + 4.0 * drive))  # (depth - h_s) * depth = drive, depth >= h_s
    d_g = params.c_d - depth
    d_v = _kernels.equilibrium_deficit(d_g, params.b, params.psi_ae, params.theta_s)
    return WalrusState(d_v=float(d_v), d_g=float(d_g), h_q=0.0, h_s=float(h_s))


#: Dry-weather specific discharge (mm/h) of the default initial state (about 0.5 mm/d).
DEFAULT_INITIAL_Q_MM_H = 0.02


@dataclass(frozen=True)
class RunoffResult:
    """Output of :func:`simulate`.

    Attributes
    ----------
    series
        One row per forcing step, indexed like the forcing (time of the step's end). Fluxes are
        mean rates over the step in mm/h over the whole catchment: ``P``, ``ETpot``, ``q``
        (specific discharge), ``ETact``, ``f_qs`` (quickflow to surface water), ``f_gs``
        (groundwater drainage to surface water; negative = infiltration). States at the step's end:
        ``d_v``, ``d_g``, ``h_q``, ``h_s`` (mm), ``W`` (-), ``storage`` (mm). ``substeps``: number
        of internal steps. ``series.attrs["units"]`` lists the units.
    initial, final
        States at the start and end (``final`` hot-starts the next run).
    params
        The parameters used.
    dt_h
        Forcing step (h).
    """

    series: pd.DataFrame
    initial: WalrusState
    final: WalrusState
    params: WalrusParameters
    dt_h: float

    @property
    def q(self) -> pd.Series:
        """Specific discharge (mm/h), mean over each step."""
        return self.series["q"]

    def water_balance(self) -> dict[str, float]:
        """Totals over the run (mm over the catchment) and the closure residual P - ETact - Q - ΔS (mm)."""
        s = self.series
        p = float(s["P"].sum() * self.dt_h)
        et = float(s["ETact"].sum() * self.dt_h)
        q = float(s["q"].sum() * self.dt_h)
        ds = self.final.storage(self.params) - self.initial.storage(self.params)
        return {"P": p, "ETact": et, "Q": q, "dS": ds, "residual": p - et - q - ds}


_UNITS = {
    "P": "mm/h", "ETpot": "mm/h", "q": "mm/h", "ETact": "mm/h", "f_qs": "mm/h", "f_gs": "mm/h",
    "d_v": "mm", "d_g": "mm", "h_q": "mm", "h_s": "mm", "W": "-", "storage": "mm", "substeps": "-",
}


def simulate(
    params: WalrusParameters,
    precip_mm_h: ArrayLike | pd.Series,
    etpot_mm_h: ArrayLike | pd.Series,
    dt_h: float = 1.0,
    initial: WalrusState | float | None = None,
    *,
    max_change_mm: float = 10.0,
    min_substep_h: float = 1e-3,
) -> RunoffResult:
    """Run the rainfall-runoff model over a forcing series.

    Parameters
    ----------
    params
        Model parameters.
    precip_mm_h
        Precipitation (mm/h), mean over each step; finite and >= 0. A Series's index is kept
        (values belong to the step ending at the index).
    etpot_mm_h
        Potential (Makkink reference) evapotranspiration (mm/h), same length; finite and >= 0.
    dt_h
        Length of a forcing step (h).
    initial
        Start state; a number is a dry-weather discharge (mm/h) for :func:`steady_state`; None
        uses :data:`DEFAULT_INITIAL_Q_MM_H`.
    max_change_mm
        Largest change of ``h_s`` or ``d_v`` within one substep (mm).
    min_substep_h
        Smallest substep (h); bounds the cost of extreme forcing.

    Returns
    -------
    RunoffResult
        The series, the initial and final states.

    Raises
    ------
    ValueError
        When the forcing has different lengths or indexes, or holds a missing, infinite or
        negative value (the message names the first one).
    """
    index_p, p = _forcing(precip_mm_h, "precip_mm_h")
    index_e, e = _forcing(etpot_mm_h, "etpot_mm_h")
    if e.size != p.size:
        raise ValueError(f"etpot_mm_h has {e.size} values, precip_mm_h has {p.size}")
    both = isinstance(precip_mm_h, pd.Series) and isinstance(etpot_mm_h, pd.Series)
    if both and not index_p.equals(index_e):
        raise ValueError("precip_mm_h and etpot_mm_h have different indexes")
    index = index_e if isinstance(etpot_mm_h, pd.Series) and not isinstance(precip_mm_h, pd.Series) else index_p
    if not (math.isfinite(dt_h) and dt_h > 0.0):
        raise ValueError(f"dt_h must be a positive step (h), got {dt_h}")
    if initial is None:
        initial = DEFAULT_INITIAL_Q_MM_H
    start = steady_state(params, float(initial)) if not isinstance(initial, WalrusState) else initial

    n = p.size
    state = start._array()
    q = np.empty(n)
    et = np.empty(n)
    fqs = np.empty(n)
    fgs = np.empty(n)
    states = np.empty((n, 4))
    w = np.empty(n)
    nsub = np.empty(n, dtype=np.int64)
    _kernels.run_walrus(p, e, float(dt_h), params._vector(max_change_mm, min_substep_h), state,
                        q, et, fqs, fgs, states, w, nsub)
    final = WalrusState(d_v=float(state[0]), d_g=float(state[1]), h_q=max(float(state[2]), 0.0),
                        h_s=max(float(state[3]), 0.0))
    a_s = params.a_s
    frame = pd.DataFrame(
        {
            "P": p, "ETpot": e, "q": q, "ETact": et, "f_qs": fqs, "f_gs": fgs,
            "d_v": states[:, 0], "d_g": states[:, 1], "h_q": states[:, 2], "h_s": states[:, 3], "W": w,
            "storage": (1.0 - a_s) * (states[:, 2] - states[:, 0]) + a_s * states[:, 3],
            "substeps": nsub,
        },
        index=index,
    )
    frame.attrs["units"] = dict(_UNITS)
    return RunoffResult(series=frame, initial=start, final=final, params=params, dt_h=float(dt_h))


def _forcing(values: ArrayLike | pd.Series, name: str) -> tuple[pd.Index, np.ndarray]:
    """Index (the Series's, or a RangeIndex) and checked float values of one forcing series."""
    if isinstance(values, pd.Series):
        index = pd.Index(values.index)
        arr = values.to_numpy(dtype=float, na_value=np.nan)
    else:
        arr = np.asarray(values, dtype=float).ravel()
        index = pd.RangeIndex(arr.size, name="step")
    if arr.size == 0:
        raise ValueError(f"{name} is empty")
    bad = np.flatnonzero(~np.isfinite(arr) | (arr < 0.0))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{name}: {bad.size} missing, infinite or negative value(s); the first is {arr[i]} "
                         f"at {index[i]} (fill or drop them before running the model)")
    return index, np.ascontiguousarray(arr)


def lateral_inflow(area_ha: float, q_mm_h: ArrayLike | pd.Series) -> np.ndarray | pd.Series | float:
    """Discharge (m³/s) of a catchment of ``area_ha`` hectares with specific discharge ``q_mm_h``.

    ``Q [m³/s] = q [mm/h] · area [ha] · 10 / 3600``: 1 mm over 1 ha is 10 m³, an hour is 3600 s.

    Parameters
    ----------
    area_ha
        Catchment (sub-)area (ha), >= 0.
    q_mm_h
        Specific discharge (mm/h): a number, an array or a Series (e.g. ``RunoffResult.q``).

    Returns
    -------
    float, numpy.ndarray or pandas.Series
        Discharge (m³/s), of the same kind as ``q_mm_h`` (a Series keeps its index and is named ``"Q"``).
    """
    if not (math.isfinite(area_ha) and area_ha >= 0.0):
        raise ValueError(f"area_ha must be a non-negative area (ha), got {area_ha}")
    factor = area_ha * 10.0 / 3600.0
    if isinstance(q_mm_h, pd.Series):
        return (q_mm_h * factor).rename("Q")
    if np.ndim(q_mm_h) == 0:
        return float(q_mm_h) * factor
    return np.asarray(q_mm_h, dtype=float) * factor
