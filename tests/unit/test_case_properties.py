"""Property: a mutated case either loads or fails at load with a CaseError, never later.

Hypothesis takes the small complete case of ``test_case_validation.mini_case`` (a bifurcation,
weirs, a culvert, a pump, boundaries of each type, laterals with CSV series, stations), applies one
to three random mutations to ``case.toml`` and ``forcing.csv`` (delete a field, change a type,
negative / zero / nan / huge numbers, unknown or swapped ids, drop or duplicate an item, reverse a
table, move a crest below the bed or a structure onto another, corrupt the CSV: gaps, duplicate or
reordered times, text in a number, a truncated period, ...), writes the case to a fresh folder and
loads it. Loading must succeed or raise :class:`~rivercal.errors.CaseError` with a one-line
message; a case that loads must compile and run for two hours or raise a rivercal error — never
any other exception.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pandas as pd
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from rivercal.case import CaseFile, EngineSettings, load_case
from rivercal.engine import Simulator, compile_network
from rivercal.errors import CaseError, RivercalError
from rivercal.network import Network
from tests.unit.test_case_validation import forcing_csv, mini_case, to_toml

REFERENCE_FIELDS = ("from_node", "to_node", "profile", "branch", "node", "structure")
ID_TABLES = ("profiles", "nodes", "branches", "weirs", "culverts", "pumps", "boundaries", "laterals", "stations")
NUMERIC_TABLES = ("heights", "flow_widths", "total_widths", "levels", "areas", "discharges")
ODD_VALUES: list[Any] = [
    -1.0, 0.0, 1e-9, 0.5, 2.0, 1e9, -1e9, 1e300, float("nan"), float("inf"), float("-inf"),
    "text", "", "3.5", True, [], {}, [1.0, 2.0], {"value": 1.0}, 7, "ghost",
]
FACTORS = [-1.0, 0.0, 1e-3, 0.5, 0.999, 1.001, 2.0, 10.0, 1e6]


# -- walking the case dict -----------------------------------------------------------------------------


def slots(node: Any) -> list[tuple[Any, Any]]:
    """Every (container, key) pair below ``node``: dict keys and list positions."""
    out: list[tuple[Any, Any]] = []
    if isinstance(node, dict):
        for key, value in node.items():
            out.append((node, key))
            out += slots(value)
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out.append((node, i))
            out += slots(value)
    return out


def pick(draw: Callable, items: list) -> Any:
    return items[draw(st.integers(0, len(items) - 1))] if items else None


def slots_where(data: dict, test: Callable[[Any, Any], bool]) -> list[tuple[Any, Any]]:
    return [(c, k) for c, k in slots(data) if test(c, k)]


# -- mutations of case.toml ------------------------------------------------------------------------------


def delete_field(draw, data, csv):
    slot = pick(draw, slots_where(data, lambda c, k: isinstance(c, dict)))
    if slot:
        del slot[0][slot[1]]
    return data, csv


def replace_value(draw, data, csv):
    slot = pick(draw, slots(data))
    if slot:
        container, key = slot
        old = container[key]
        if isinstance(old, int | float) and not isinstance(old, bool) and draw(st.booleans()):
            container[key] = old * draw(st.sampled_from(FACTORS))
        else:
            container[key] = draw(st.sampled_from(ODD_VALUES))
    return data, csv


def nudge_number(draw, data, csv):
    """A plausible change that often still loads: scale a number a little, so the engine runs odd cases."""
    slot = pick(draw, slots_where(data, lambda c, k: isinstance(c[k], int | float) and not isinstance(c[k], bool)))
    if slot:
        slot[0][slot[1]] = slot[0][slot[1]] * draw(st.sampled_from([0.5, 0.9, 0.99, 1.01, 1.1, 1.5, 3.0]))
    return data, csv


def unknown_id(draw, data, csv):
    slot = pick(draw, slots_where(data, lambda c, k: isinstance(c, dict) and k in REFERENCE_FIELDS))
    if slot:
        slot[0][slot[1]] = draw(st.sampled_from(["ghost", "J1", "b3", "W2", "U1", "D", "zw", "P1"]))
    return data, csv


def swap_ids(draw, data, csv):
    refs = slots_where(data, lambda c, k: isinstance(c, dict) and k in (*REFERENCE_FIELDS, "id"))
    a, b = pick(draw, refs), pick(draw, refs)
    if a and b:
        a[0][a[1]], b[0][b[1]] = b[0][b[1]], a[0][a[1]]
    return data, csv


def drop_item(draw, data, csv):
    table = draw(st.sampled_from([*ID_TABLES, "cross_sections"]))
    lists = slots_where(data, lambda c, k: isinstance(c, dict) and k == table and isinstance(c[k], list))
    slot = pick(draw, lists)
    if slot and slot[0][slot[1]]:
        items = slot[0][slot[1]]
        del items[draw(st.integers(0, len(items) - 1))]
    return data, csv


def duplicate_item(draw, data, csv):
    table = draw(st.sampled_from(ID_TABLES))
    items = data.get(table)
    if isinstance(items, list) and items:
        item = pick(draw, items)
        items.append(dict(item) if isinstance(item, dict) else item)
    return data, csv


def reverse_table(draw, data, csv):
    lists = slots_where(data, lambda c, k: isinstance(c, dict) and k in (*NUMERIC_TABLES, "cross_sections")
                        and isinstance(c[k], list))
    slot = pick(draw, lists)
    if slot:
        values = slot[0][slot[1]]
        if draw(st.booleans()):
            values.reverse()
        elif len(values) >= 2:
            i = draw(st.integers(0, len(values) - 2))
            values[i], values[i + 1] = values[i + 1], values[i]
    return data, csv


def below_the_bed(draw, data, csv):
    field = draw(st.sampled_from([("weirs", "crest_level"), ("culverts", "invert_level"), ("pumps", "stop_level")]))
    items = data.get(field[0])
    if isinstance(items, list) and items and isinstance(items[0], dict):
        items[0][field[1]] = draw(st.sampled_from([-5.0, 0.0, 2.0, 3.0, 3.5, 3.6799, 3.68, 3.9]))
    return data, csv


def move_structure(draw, data, csv):
    tables = [t for t in ("weirs", "culverts", "pumps") if isinstance(data.get(t), list) and data[t]]
    if len(tables) >= 1:
        table = draw(st.sampled_from(tables))
        item = pick(draw, data[table])
        other = pick(draw, [s for t in tables for s in data[t] if isinstance(s, dict)])
        if isinstance(item, dict) and isinstance(other, dict):
            item["branch"] = other.get("branch", "b2")
            base = other.get("chainage", 600.0)
            base = base if isinstance(base, int | float) and not isinstance(base, bool) else 600.0
            item["chainage"] = base + draw(st.sampled_from([-25.0, -10.0, -5.0, -0.1, 0.0, 3.0, 9.99, 10.0, 40.0]))
    return data, csv


def move_location(draw, data, csv):
    slot = pick(draw, slots_where(data, lambda c, k: isinstance(c, dict) and k == "chainage"))
    if slot:
        slot[0][slot[1]] = draw(st.sampled_from([0.0, 1.0, 5.0, 124.0, 126.0, 1199.0, 1450.0, 1500.0, 1800.0,
                                                 2000.0, 2000.5, 5000.0, -3.0]))
    return data, csv


def lateral_to_a_node(draw, data, csv):
    laterals = data.get("laterals")
    if isinstance(laterals, list) and laterals and isinstance(laterals[0], dict):
        lat = laterals[draw(st.integers(0, len(laterals) - 1))]
        if isinstance(lat, dict):
            lat.pop("branch", None)
            lat.pop("chainage", None)
            lat["node"] = draw(st.sampled_from(["U1", "J1", "J2", "D", "R", "U2"]))
    return data, csv


def station_quantity(draw, data, csv):
    stations = data.get("stations")
    if isinstance(stations, list) and stations and isinstance(stations[0], dict):
        st_ = stations[draw(st.integers(0, len(stations) - 1))]
        if isinstance(st_, dict):
            st_["quantities"] = draw(st.lists(st.sampled_from(["h", "h_up", "h_down", "Q", "q", "level"]),
                                              max_size=4))
    return data, csv


def change_period(draw, data, csv):
    case = data.get("case")
    if isinstance(case, dict):
        key = draw(st.sampled_from(["start", "end"]))
        case[key] = draw(st.sampled_from([
            "2019-12-31T20:00:00Z", "2020-01-01T01:00:00Z", "2020-01-01T00:30:00Z", "2020-01-01T02:00:00",
            "2020-01-02T02:00:00Z", "2020-01-02T03:00:00Z", "2020-01-03T00:00:00Z", "2020-01-01T00:00:00+01:00",
            "1600-01-01T00:00:00Z", "9999-01-01T00:00:00Z", "yesterday", "2020-02-30T00:00:00Z",
        ]))
    return data, csv


def add_unknown_field(draw, data, csv):
    slot = pick(draw, slots_where(data, lambda c, k: isinstance(c, dict) and isinstance(c[k], dict)))
    target = slot[0][slot[1]] if slot else data
    target[draw(st.sampled_from(["crest_levle", "comment", "widht", "type"]))] = 1.0
    return data, csv


# -- mutations of forcing.csv -------------------------------------------------------------------------------


def csv_lines(csv: str) -> list[str]:
    return csv.splitlines()


def drop_line(draw, data, csv):
    lines = csv_lines(csv)
    if len(lines) > 1:
        del lines[draw(st.integers(1, len(lines) - 1))]
    return data, "\n".join(lines) + "\n"


def duplicate_line(draw, data, csv):
    lines = csv_lines(csv)
    if len(lines) > 1:
        i = draw(st.integers(1, len(lines) - 1))
        lines.insert(i, lines[i])
    return data, "\n".join(lines) + "\n"


def swap_lines(draw, data, csv):
    lines = csv_lines(csv)
    if len(lines) > 2:
        i = draw(st.integers(1, len(lines) - 2))
        lines[i], lines[i + 1] = lines[i + 1], lines[i]
    return data, "\n".join(lines) + "\n"


def corrupt_cell(draw, data, csv):
    lines = csv_lines(csv)
    if lines:
        i = draw(st.integers(0, len(lines) - 1))
        cells = lines[i].split(",")
        j = draw(st.integers(0, len(cells) - 1))
        cells[j] = draw(st.sampled_from(["", "abc", "nan", "inf", "-inf", "1,5", "1e400", " 2.0 ", "-1e9", "0",
                                         "2020-01-01T00:00:00Z", "2020-13-01T00:00:00Z", "\"x\"", "1e-400"]))
        lines[i] = ",".join(cells)
    return data, "\n".join(lines) + "\n"


def truncate_period(draw, data, csv):
    lines = csv_lines(csv)
    k = draw(st.integers(1, 6))
    if draw(st.booleans()):
        lines = lines[:1] + lines[1 + k:]
    else:
        lines = lines[:-k]
    return data, "\n".join(lines) + "\n"


def drop_column(draw, data, csv):
    rows = [line.split(",") for line in csv_lines(csv)]
    if rows:
        j = draw(st.integers(0, len(rows[0]) - 1))
        rows = [r[:j] + r[j + 1:] for r in rows]
    return data, "\n".join(",".join(r) for r in rows) + "\n"


def ragged_or_empty(draw, data, csv):
    kind = draw(st.sampled_from(["empty", "header only", "extra field", "missing field", "bad header", "binary"]))
    lines = csv_lines(csv) or [""]
    row = min(3, len(lines) - 1)
    if kind == "empty":
        return data, ""
    if kind == "header only":
        return data, lines[0] + "\n"
    if kind == "extra field":
        lines[row] += ",9.9"
    elif kind == "missing field":
        lines[row] = lines[row].rsplit(",", 1)[0]
    elif kind == "bad header":
        lines[0] = lines[0].replace("L1", "Q_U1")
    else:
        return data, "\udcff\udcfe\x00" + csv
    return data, "\n".join(lines) + "\n"


TOML_MUTATIONS = [delete_field, replace_value, nudge_number, unknown_id, swap_ids, drop_item, duplicate_item,
                  reverse_table, below_the_bed, move_structure, move_location, lateral_to_a_node, station_quantity,
                  change_period, add_unknown_field]
CSV_MUTATIONS = [drop_line, duplicate_line, swap_lines, corrupt_cell, truncate_period, drop_column, ragged_or_empty]


@st.composite
def mutated_cases(draw) -> tuple[dict, str, list[str]]:
    data, csv = mini_case(), forcing_csv()
    applied = []
    for _ in range(draw(st.integers(1, 3))):
        mutation = draw(st.sampled_from(TOML_MUTATIONS + CSV_MUTATIONS))
        applied.append(mutation.__name__)
        data, csv = mutation(draw, data, csv)
    return data, csv, applied


def two_hours(case) -> pd.Timestamp:
    """``start + 2 h``, rounded to whole output intervals within the period."""
    interval = case.spec.engine.output_interval
    period = (case.end - case.start).total_seconds()
    n = max(1, int(7200.0 // interval))
    return case.start + pd.Timedelta(seconds=min(n * interval, period))


@settings(max_examples=600, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_cases())
def test_a_mutated_case_loads_or_fails_with_a_case_error(example) -> None:
    data, csv, applied = example
    note(f"mutations: {applied}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "case.toml").write_text(to_toml(data), encoding="utf-8")
        (folder / "forcing.csv").write_bytes(csv.encode("utf-8", errors="surrogateescape"))
        try:
            case = load_case(folder)
        except CaseError as exc:
            message = str(exc)
            note(message)
            assert message.strip(), "a CaseError needs a message"
            assert "\n" not in message, message
            assert str(folder) in message, message  # names the file
            event("rejected at load")
            return
        try:
            sim = Simulator(case)
            sim.simulate(end=two_hours(case))
        except CaseError as exc:  # the case loaded, so this is a check missing at load
            raise AssertionError(f"a loaded case failed later: {exc}") from exc
        except RivercalError as exc:
            note(f"{type(exc).__name__}: {exc}")
            event(f"loaded; engine raised {type(exc).__name__}")
            return
        event("loaded and ran")


GAPS = st.one_of(st.sampled_from([0.25, 0.5, 0.75, 0.99, 0.999999, 1.0, 1.000001, 1.01, 2.0]), st.floats(0.0, 3.0))


@settings(max_examples=300, deadline=None)
@given(
    length=st.one_of(st.floats(1.0, 3000.0), st.sampled_from([10.0, 20.0, 30.0])),
    structure_length=st.one_of(st.floats(0.1, 100.0), st.just(10.0)),
    first=st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 1.0])),
    gaps=st.lists(GAPS, min_size=0, max_size=3),
    kinds=st.lists(st.sampled_from(["weir", "culvert", "pump"]), min_size=4, max_size=4),
)
def test_structure_spacing_at_load_agrees_with_the_engine(length, structure_length, first, gaps, kinds) -> None:
    """The load-time spacing check agrees with the compiler: what loads compiles, what cannot compile fails to load."""
    where = [first * length]
    for gap in gaps:  # distances in units of the structure length, where the verdict flips
        where.append(min(where[-1] + gap * structure_length, length))
    data = mini_case()
    b2 = data["branches"][1]
    b2["length"] = length
    b2["cross_sections"][1]["chainage"] = length
    data["engine"]["structure_length"] = structure_length
    data["weirs"] = [data["weirs"][1]]
    data["culverts"], data["pumps"] = [], []
    data["stations"] = [s for s in data["stations"] if "structure" not in s]
    for i, (chainage, kind) in enumerate(zip(where, kinds, strict=False)):
        common = {"id": f"S{i}", "branch": "b2", "chainage": chainage}
        if kind == "weir":
            data["weirs"].append({**common, "crest_level": 9.0, "crest_width": 2.0})
        elif kind == "culvert":
            data["culverts"].append({**common, "shape": "circular", "diameter": 0.5, "invert_level": 9.0,
                                     "length": 5.0})
        else:
            data["pumps"].append({**common, "capacity": 0.1, "start_level": 9.5, "stop_level": 9.0})
    try:
        CaseFile.model_validate(data)
        loads = True
    except ValidationError as exc:
        assert "too close" in str(exc), str(exc)
        loads = False
    network = Network.model_validate({k: v for k, v in data.items() if k in Network.model_fields})
    try:
        compile_network(network, EngineSettings.model_validate(data["engine"]))
        compiles = True
    except CaseError:
        compiles = False
    event("loads" if loads else "rejected at load")
    assert loads == compiles


def test_the_unmutated_case_loads_and_runs() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        (folder / "case.toml").write_text(to_toml(mini_case()), encoding="utf-8")
        (folder / "forcing.csv").write_text(forcing_csv(), encoding="utf-8")
        case = load_case(folder)
        result, _ = Simulator(case).simulate(end=two_hours(case))
        assert len(result.series) == 3
