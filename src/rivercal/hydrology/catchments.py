"""Lateral inflows of a case's sub-catchments, computed once before any hydrodynamic run.

A case with ``[meteo]``, ``[runoff]`` and ``[[catchments]]`` (see ``docs/case-format.md``) lets the
rainfall-runoff model make the inflow of laterals and discharge boundaries that say
``catchment = "<id>"`` (thesis §3-1-2: the RR relations are computed before the optimisation and
stay the same for every calibration run):

1. the meteo file is read (:func:`~rivercal.hydrology.knmi.read_knmi_daily`) and disaggregated to
   hours (:func:`~rivercal.hydrology.disaggregate.hourly_forcing`);
2. each catchment runs :func:`~rivercal.hydrology.runoff.simulate` with the ``[runoff]``
   parameters, overridden by its own ``runoff`` table, from a dry-weather steady state;
3. the specific discharge (mm per hour ending at the index) becomes m³/s for the catchment area
   (:func:`~rivercal.hydrology.runoff.lateral_inflow`) and is placed at the middle of its hour, so
   that the engine's linear interpolation keeps the hourly volumes; before the first hour the first
   value holds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np
import pandas as pd

from rivercal.case.load import CASE_FILE, Case
from rivercal.errors import CaseError
from rivercal.hydrology.disaggregate import hourly_forcing
from rivercal.hydrology.knmi import read_knmi_daily
from rivercal.hydrology.runoff import WalrusParameters, lateral_inflow, simulate

__all__ = ["catchment_forcing", "hourly_weather", "runoff_parameters"]


def runoff_parameters(case: Case, overrides: dict[str, float], field: str) -> WalrusParameters:
    """The model parameters for one catchment: defaults, then ``[runoff]``, then ``overrides``.

    Raises
    ------
    CaseError
        For an unknown parameter name or an invalid value, naming the field.
    """
    names = {f.name for f in dataclasses.fields(WalrusParameters)}
    params = WalrusParameters()
    for where, table in (("runoff", case.spec.runoff), (field, overrides)):
        unknown = sorted(set(table) - names)
        if unknown:
            raise CaseError(f"unknown rainfall-runoff parameter {unknown[0]!r} (known: {', '.join(sorted(names))})",
                            file=str(case.root / CASE_FILE), field=f"{where}.{unknown[0]}")
        try:
            params = params.replace(**table)
        except (ValueError, TypeError) as exc:
            raise CaseError(str(exc), file=str(case.root / CASE_FILE), field=where) from None
    return params


def hourly_weather(case: Case) -> pd.DataFrame:
    """Hourly rain ``P`` and Makkink evaporation ``ETpot`` (mm per hour ending at the index, UTC) of the period.

    The rows are the hours that end after the case's start and at most one hour after its end (what
    :func:`catchment_forcing` runs the rainfall-runoff model over).

    Raises
    ------
    CaseError
        When the meteo file is invalid or the weather does not cover the period (or has gaps in it).
    """
    meteo = case.spec.meteo
    daily = read_knmi_daily(case.root / meteo.file)
    hourly = hourly_forcing(daily, lat_deg=meteo.latitude, lon_deg=meteo.longitude)
    start, end = case.start, case.end
    first_hour_start = hourly.index[0] - pd.Timedelta(hours=1)
    if first_hour_start > start or hourly.index[-1] < end:
        raise CaseError(
            f"the weather covers {first_hour_start.isoformat()} .. {hourly.index[-1].isoformat()}, which does not "
            f"cover the simulated period {start.isoformat()} .. {end.isoformat()}",
            file=str(case.root / meteo.file), field="meteo.file",
        )
    period = hourly.loc[(hourly.index > start) & (hourly.index <= end + pd.Timedelta(hours=1))]
    gaps = period.index[period.isna().any(axis=1)]
    if gaps.size:
        raise CaseError(f"the weather has missing rain or evaporation for {gaps.size} hours in the simulated period, "
                        f"the first ending at {gaps[0].isoformat()} (KNMI columns RH, RHX, RHXH, DR, EV24)",
                        file=str(case.root / meteo.file), field="meteo.file")
    return period


def catchment_forcing(case: Case, *, rain_factor: pd.Series | None = None,
                      parameter_factors: Mapping[str, Mapping[str, float]] | None = None) -> dict[str, pd.Series]:
    """Inflow series (m³/s, UTC index) of every lateral and boundary fed by a catchment.

    Parameters
    ----------
    case
        The case.
    rain_factor
        A factor (-) on the rain of each hour (indexed like :func:`hourly_weather`; hours not in it keep
        their rain), e.g. the rainfall error of a twin experiment's truth. Default: the measured rain.
    parameter_factors
        Per catchment id, factors (-) on its rainfall-runoff parameters (names of
        :class:`~rivercal.hydrology.runoff.WalrusParameters`), e.g. the runoff-parameter error of a twin
        experiment's truth. Default: the case's parameters.

    Returns
    -------
    dict
        Keys ``"lateral:<id>"`` / ``"boundary:<id>"`` as in :attr:`rivercal.case.Case.forcing`.

    Raises
    ------
    CaseError
        When the meteo file or a parameter is invalid, or the weather does not cover the period.
    ValueError
        For a negative or non-finite rain factor, or a factor of an unknown catchment or parameter.
    """
    spec = case.spec
    if not spec.catchments:
        return {}
    hourly = hourly_weather(case)
    if rain_factor is not None:
        factor = pd.Series(rain_factor, dtype=float).reindex(hourly.index).fillna(1.0)
        if not (np.isfinite(factor).all() and (factor >= 0).all()):
            raise ValueError("rain_factor: every factor must be finite and >= 0")
        hourly = hourly.assign(P=hourly["P"] * factor)
    factors = dict(parameter_factors or {})
    unknown = sorted(set(factors) - {c.id for c in spec.catchments})
    if unknown:
        raise ValueError(f"parameter_factors: unknown catchment {unknown[0]!r}")
    start = case.start
    mid = hourly.index - pd.Timedelta(minutes=30)
    inflow: dict[str, pd.Series] = {}
    for i, c in enumerate(spec.catchments):
        params = runoff_parameters(case, c.runoff, f"catchments[{i}].runoff")
        if c.id in factors:
            params = _scaled(params, factors[c.id], c.id)
        q = simulate(params, hourly["P"], hourly["ETpot"]).q
        discharge = pd.Series(lateral_inflow(c.area, q.to_numpy()), index=mid)
        head = pd.Series([discharge.iloc[0]], index=[min(start, mid[0])])
        inflow[c.id] = pd.concat([head, discharge]) if head.index[0] < mid[0] else discharge
    out = {}
    for kind, items in (("lateral", spec.laterals), ("boundary", spec.boundaries)):
        for item in items:
            if item.catchment is not None:
                out[f"{kind}:{item.id}"] = inflow[item.catchment].rename(f"{kind}:{item.id}")
    return out


def _scaled(params: WalrusParameters, factors: Mapping[str, float], catchment: str) -> WalrusParameters:
    """``params`` with some parameters multiplied by factors (-)."""
    names = {f.name for f in dataclasses.fields(WalrusParameters)}
    unknown = sorted(set(factors) - names)
    if unknown:
        raise ValueError(f"parameter_factors[{catchment!r}]: unknown rainfall-runoff parameter {unknown[0]!r}")
    return params.replace(**{k: getattr(params, k) * float(v) for k, v in factors.items()})
