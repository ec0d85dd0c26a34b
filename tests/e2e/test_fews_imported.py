"""``rivercal fews`` on shared real models as imported, wired as a water board wires them in Delft-FEWS.

FEWS is played here: it exports the observed levels at the imported model's own stations (a twin: the model
itself, run with its own parameters), the model's boundary, lateral and structure-setting series at their own
ids (what FEWS holds for them: the model's own series, changed from a time on as a forecast would change them),
a PI run file in CET, and after each run it hands the state on. The PI files are written and read with plain
``xml.etree``, every file rivercal writes is validated against the shared PI schemas, and the second forecast
is compared with an uninterrupted run of the imported model with the parameters the forecasts used.

Dellen (D-HYDRO, imported with its two ``--realtime`` files, 10-minute output) runs at ``timeStep`` 10 min; the
SOBEK 3 compound channel at its own hourly step. Dellen's FEWS forcing exercises what the imported model brings:
a pump that real-time control kept off all week now pumping 2 m³/s (of its 5.3), a weir crest raised, a shower on a
lateral whose own week never reached a thousandth of a cubic metre per second, and evaporation drawing from a
lateral whose own series is never negative.
"""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.cli import rivercal
from tests.conftest import assert_valid_pi
from tests.run_artefacts import dellen
from tests.shared_data import shared_model

NS = "http://www.wldelft.nl/fews/PI"
ZONE_H = 1.0  # FEWS exports in CET
#: The parameterId FEWS uses for each kind of forcing (a boundary takes h or Q by its type).
PARAMETER = {"lateral": "Q", "crest": "crestLevel", "gate": "gateLowerEdgeLevel", "capacity": "capacity"}
#: Forecasts are written with 10 significant digits: a level below 100 m is rounded by at most 5e-9 m. The hand-over
#: keeps the model state as the engine holds it and every run restarts at the same step boundaries, so the forecast
#: after a hand-over is the uninterrupted run up to that rounding (measured: 5.0e-10 m on both models, whose levels
#: lie below 10 m); a forecast without the state (a cold spin-up on the case's own forcing before FEWS's second
#: export) is off by 9.2 mm (Dellen) and 0.26 mm (compound channel, which forgets its start sooner).
TOLERANCE_M = 1e-8
#: Least difference a forecast without the state would show at some station (checked, so the test can fail): ten
#: thousand times the hand-over's tolerance.
WITHOUT_STATE_M = 1e-4


@dataclass(frozen=True)
class Imported:
    """A shared model, how it is imported, and one FEWS set-up for it (UTC times)."""

    parts: tuple[str, ...]
    importer: str
    extra: tuple[str, ...]
    parameter: str
    t0: str
    step: str  # the run file's timeStep
    window: str
    observed: tuple[str, ...]  # the series FEWS exports as observations (the model's own station ids)
    changes: dict[str, float] = field(default_factory=dict)  # forcing key -> value from CHANGE_AFTER on
    scale: dict[str, float] = field(default_factory=dict)  # forcing key -> factor from CHANGE_AFTER on


MODELS = {
    "dellen": Imported(("dhydro-dellen", "dflowfm", "Flow1D.mdu"), "dhydro",
                       ("--realtime", "rr_to_flow.nc", "--realtime", "rtc_to_flow.nc"), "F_Manning_0_03",
                       "2000-06-01T03:00", "10min", "1h",
                       ("ObservationPoint_KST-O-17690.h", "ObservationPoint_KST-O-17755.h",
                        "ObservationPoint_PMP_KGM-O-11730.h", "KST-O-17660.h_up"),
                       changes={"capacity:PMP_KGM-O-11730": 2.0, "crest:KST-O-17660": -1.2,
                                "lateral:ucGRASLANDVEENGPG-O-17760": 0.01,
                                "lateral:ucAKKERBOUW_TUINBOUWKLEIGPG-O-17685": -0.0005}),
    "sobek3-compound": Imported(("sobek3-compound", "test_compound.dsproj_data", "Flow1D_output", "dflow1d",
                                 "Flow1D.md1d"), "sobek3", (), "F_scale", "2001-01-01T04:00", "1h", "1h",
                                ("Channel1_middle.h",), scale={"boundary:Node001": 2.0}),
}


def q(tag: str) -> str:
    return f"{{{NS}}}{tag}"


def local(t: pd.Timestamp) -> dict[str, str]:
    loc = (t + pd.Timedelta(hours=ZONE_H)).tz_localize(None)
    return {"date": loc.strftime("%Y-%m-%d"), "time": loc.strftime("%H:%M:%S")}


def utc(node: ET.Element) -> pd.Timestamp:
    return (pd.Timestamp(f"{node.get('date')}T{node.get('time')}") - pd.Timedelta(hours=ZONE_H)).tz_localize("UTC")


def export(path: Path, series: dict[tuple[str, str], pd.Series], step_s: float) -> None:
    """FEWS's export of equidistant series (location, parameter) -> values, in CET."""
    ET.register_namespace("", NS)
    root = ET.Element(q("TimeSeries"), version="1.2")
    ET.SubElement(root, q("timeZone")).text = f"{ZONE_H:.1f}"
    for (loc, par), values in series.items():
        s = ET.SubElement(root, q("series"))
        h = ET.SubElement(s, q("header"))
        for tag, text in (("type", "instantaneous"), ("locationId", loc), ("parameterId", par)):
            ET.SubElement(h, q(tag)).text = text
        ET.SubElement(h, q("timeStep"), unit="second", multiplier=str(int(step_s)))
        ET.SubElement(h, q("startDate"), local(values.index[0]))
        ET.SubElement(h, q("endDate"), local(values.index[-1]))
        ET.SubElement(h, q("missVal")).text = "-999.0"
        ET.SubElement(h, q("units")).text = "m3/s" if par in ("Q", "capacity") else "m"
        for t, v in values.items():
            ET.SubElement(s, q("event"), {**local(t), "value": repr(float(v)), "flag": "0"})
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)


def write_run_file(module: Path, t0: pd.Timestamp, *, state: bool, properties: dict[str, str]) -> Path:
    ET.register_namespace("", NS)
    root = ET.Element(q("Run"), version="1.8")
    ET.SubElement(root, q("logLevel")).text = "info"
    ET.SubElement(root, q("timeZone")).text = f"{ZONE_H:.1f}"
    ET.SubElement(root, q("startDateTime"), local(t0 - pd.Timedelta("1D")))
    ET.SubElement(root, q("endDateTime"), local(t0 + pd.Timedelta("1D")))
    ET.SubElement(root, q("time0"), local(t0))
    ET.SubElement(root, q("workDir")).text = "."
    if state:
        ET.SubElement(root, q("inputStateDescriptionFile")).text = "input/state.xml"
    for name in ("input/observations.xml", "input/forcing.xml"):
        ET.SubElement(root, q("inputTimeSeriesFile")).text = name
    for tag, name in (("outputDiagnosticFile", "diag.xml"), ("outputStateDescriptionFile", "state.xml"),
                      ("outputTimeSeriesFile", "forecasts.xml"), ("outputTimeSeriesFile", "estimates.xml")):
        ET.SubElement(root, q(tag)).text = f"output/{name}"
    props = ET.SubElement(root, q("properties"))
    for key, value in properties.items():
        ET.SubElement(props, q("string"), key=key, value=value)
    path = module / "run_info.xml"
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path


def read_series(path: Path) -> dict[tuple[str, str, tuple[str, ...]], pd.Series]:
    """(location, parameter, qualifiers) -> values at UTC times, read independently of rivercal."""
    root = ET.parse(path).getroot()
    assert float(root.findtext(q("timeZone"))) == ZONE_H
    out = {}
    for s in root.findall(q("series")):
        h = s.find(q("header"))
        key = (h.findtext(q("locationId")), h.findtext(q("parameterId")),
               tuple(n.text for n in h.findall(q("qualifierId"))))
        events = s.findall(q("event"))
        out[key] = pd.Series([float(e.get("value")) for e in events], index=pd.DatetimeIndex([utc(e) for e in events]))
    return out


def truth_forcing(case, spec: Imported, change_after: pd.Timestamp, grid: pd.DatetimeIndex) -> dict[str, pd.Series]:
    """What FEWS holds for every forcing series of the case, on ``grid``: the case's own values, changed after
    ``change_after`` as ``spec`` says."""
    out = {}
    for key, own in case.forcing.items():
        values = np.interp(grid.as_unit("ns").asi8, own.index.as_unit("ns").asi8, own.to_numpy(float))
        later = grid > change_after
        if key in spec.changes:
            values[later] = spec.changes[key]
        if key in spec.scale:
            values[later] *= spec.scale[key]
        out[key] = pd.Series(values, index=grid)
    return out


def merged(own: pd.Series, fews: pd.Series) -> pd.Series:
    """The case's own series with FEWS's values in place over the span FEWS exported (as the module merges)."""
    outside = own[(own.index < fews.index[0]) | (own.index > fews.index[-1])]
    return pd.concat([outside, fews]).sort_index()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dellen", "sobek3-compound"])
def test_two_forecasts_on_an_imported_model_hand_the_state_on(tmp_path: Path, name: str, pi_schema) -> None:
    from rivercal.model import load_model
    from rivercal.models import EmbeddedModel

    spec = MODELS[name]
    source = shared_model(*spec.parts)
    extra = tuple(str(source.parents[1] / x) if x.endswith(".nc") else x for x in spec.extra)
    case_dir = tmp_path / "case"
    if name == "dellen":  # the same import (its two exchange files), made once in the run for the modules that need it
        dellen(case_dir)
    else:
        run = rivercal("import", spec.importer, str(source), "--out", str(case_dir), *extra, "--json")
        assert run.returncode == 0, run.stderr
    model = load_model(case_dir)
    case = model.case
    step = pd.Timedelta(spec.step)
    window = warmup = period = horizon = pd.Timedelta(spec.window)
    t0s = [pd.Timestamp(spec.t0, tz="UTC"), pd.Timestamp(spec.t0, tz="UTC") + period]
    spans = [(t - window - warmup - pd.Timedelta("1h"), t + horizon + pd.Timedelta("1h")) for t in t0s]
    change_after = spans[0][0] + pd.Timedelta("30min")  # inside the first export, before the second starts
    assert change_after < spans[1][0]
    grid = pd.date_range(spans[0][0], spans[1][1], freq=step)
    truth = truth_forcing(case, spec, change_after, grid)
    # the imported model on FEWS's forcing, uninterrupted: the twin whose levels FEWS exports as observations
    reference = EmbeddedModel(case, forcing={k: merged(case.forcing[k], s) for k, s in truth.items()})
    initial = {p.name: p.initial for p in model.calibration.parameters}
    known = {p.name: p for p in model.calibration.parameters}
    twin, _ = reference.simulate(known[spec.parameter].quantities(initial[spec.parameter]), model.start,
                                 t0s[1] + horizon, output_interval=step.total_seconds())
    kinds = {b.id: b.type for b in case.network.boundaries}
    module = tmp_path / "Modules" / "rivercal"
    props = {"case": str(case_dir), "parameters": spec.parameter, "window": spec.window, "warmup": spec.window,
             "period": spec.window, "horizon": spec.window, "timeStep": spec.step, "workers": "1", "run": "fews"}
    stations = {s.id: {o.rpartition(".")[2] for o in s.observables} for s in case.network.stations}
    used = []
    for k, t0 in enumerate(t0s):
        # FEWS's side before the run: the exports, the state of the previous run, an empty output folder
        observed = {tuple(c.rsplit(".", 1)): twin.series[c].loc[t0 - window - warmup:t0] for c in spec.observed}
        export(module / "input" / "observations.xml", observed, step.total_seconds())
        forcing = {}
        for key, values in truth.items():
            kind, _, ident = key.partition(":")
            parameter = PARAMETER.get(kind) or ("h" if kinds[ident] == "level" else "Q")
            forcing[(ident, parameter)] = values.loc[spans[k][0]:spans[k][1]]
        export(module / "input" / "forcing.xml", forcing, step.total_seconds())
        if k:
            loc = ET.parse(module / "output" / "state.xml").getroot().find(q("stateLoc"))
            written, read = module / loc.findtext(q("writeLocation")), module / loc.findtext(q("readLocation"))
            shutil.copyfile(written, tmp_path / "fews-db.sqlite")  # into FEWS's database ...
            shutil.copyfile(tmp_path / "fews-db.sqlite", read)  # ... and out again to the read location
            shutil.copyfile(module / "output" / "state.xml", module / "input" / "state.xml")
            shutil.rmtree(module / "output")
        run_file = write_run_file(module, t0, state=k > 0, properties=props)
        run = rivercal("fews", "--json", str(run_file))
        assert run.returncode == 0, run.stderr
        summary = json.loads(run.stdout)
        assert summary["cycle"] == k and pd.Timestamp(summary["issue_time"]) == t0
        out = module / "output"
        for file, schema in (("forecasts.xml", "pi_timeseries.xsd"), ("estimates.xml", "pi_timeseries.xsd"),
                             ("state.xml", "pi_state.xsd"), ("diag.xml", "pi_diag.xsd")):
            if k or file != "forecasts.xml":  # the same writer twice: a megabyte for Dellen, validated once
                assert_valid_pi(pi_schema(schema), out / file)
        diag = [(int(n.get("level")), n.get("description")) for n in ET.parse(out / "diag.xml").getroot()]
        assert min(level for level, _ in diag) >= 2, diag
        assert any("forcing from FEWS at" in text for _, text in diag)
        assert any("cold start" in text for _, text in diag) == (k == 0)
        forecasts = read_series(out / "forecasts.xml")
        # at the model's own station ids, every quantity each simulates, from time0 on the run's time step
        assert {(loc, par) for loc, par, _ in forecasts} == {(s, x) for s, xs in stations.items() for x in xs}
        some = forecasts[(*spec.observed[0].rsplit(".", 1), ("updated",))]
        assert some.index[0] == t0 and some.index[-1] == t0 + horizon and (np.diff(some.index) == step).all()
        estimates = read_series(out / "estimates.xml")
        used.append(estimates[(case.name, spec.parameter, ("used",))].iloc[0])
    # the second forecast starts from the first's state: the uninterrupted run with the parameters the forecasts
    # used (the initial value until the first window, then each forecast's) gives its levels
    q0, q1 = (known[spec.parameter].quantities(v) for v in used)
    run_start = t0s[0] - window - warmup
    _, s = reference.simulate(known[spec.parameter].quantities(initial[spec.parameter]), model.start, run_start)
    _, s = reference.simulate(q0, run_start, run_start + period, state=s)
    after, _ = reference.simulate(q1, run_start + period, t0s[1] + horizon, state=s,
                                  output_interval=step.total_seconds())
    # ... and the DSS's, the model as it is, the twin itself; without the state the forecast is off
    cold = EmbeddedModel(case, forcing={k: merged(case.forcing[k], v.loc[spans[1][0]:]) for k, v in truth.items()})
    without, _ = cold.simulate({}, model.start, t0s[1] + horizon, output_interval=step.total_seconds())
    times = pd.date_range(t0s[1], t0s[1] + horizon, freq=step)
    levels = [c for c in twin.series.columns if c.rpartition(".")[2] in ("h", "h_up", "h_down")]
    worst_updated = worst_dss = worst_without = 0.0
    for column in levels:
        station, _, quantity = column.rpartition(".")
        worst_updated = max(worst_updated, float(np.abs(forecasts[(station, quantity, ("updated",))].to_numpy()
                                                        - after.series[column].loc[times].to_numpy()).max()))
        worst_dss = max(worst_dss, float(np.abs(forecasts[(station, quantity, ("dss",))].to_numpy()
                                                - twin.series[column].loc[times].to_numpy()).max()))
        worst_without = max(worst_without, float(np.abs(without.series[column].loc[times].to_numpy()
                                                        - twin.series[column].loc[times].to_numpy()).max()))
    assert worst_updated < TOLERANCE_M and worst_dss < TOLERANCE_M, (worst_updated, worst_dss)
    assert worst_without > WITHOUT_STATE_M, worst_without
