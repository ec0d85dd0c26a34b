"""Fuzz: observation files as the on-line service ingests them end in stored values or a clean error.

A seeded generator mutates a valid CSV file and a valid Delft-FEWS PI-XML file of the toy river's two
gauges (``test_online_service``) — cells, times, headers, flags, units, time zones, duplicated and swapped
lines, truncation, stray bytes, long fields, foreign delimiters, DTDs, namespaces — and hands each file to
:func:`rivercal.workflows.online.ingest_file`, what ``rivercal online --follow`` does with every new file
(read, check against the model, store). Every case must end in one of two ways:

- stored: then what the store holds for the file is what an independent reading of the file gives (the
  CSV by :mod:`csv` and :meth:`datetime.fromisoformat`; PI-XML values must be values of the file's events);
- a :class:`~rivercal.errors.CaseError` whose message names the file and stays short, with nothing of
  the file stored;

never another exception (an internal error). PI flags that are not ASCII digits or exceed a 32-bit number
(``²``, 10^20) are the PI reader's own refusal, made and tested with the Delft-FEWS module's PI checks; this
generator keeps to ASCII flags below 2^63.
"""

from __future__ import annotations

import csv
import io
import math
import random
import re
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rivercal.errors import CaseError
from rivercal.io import write_observations_csv
from rivercal.io.pixml import write_pixml
from rivercal.online.screening import plausible_ranges
from rivercal.store import Store
from rivercal.workflows.online import ingest_file
from tests.unit.test_online_service import ToyRiver, _observations

#: Cases per format (about 5 ms each).
CASES = 300
FIRST = pd.Timestamp("2010-10-25", tz="UTC")

CELLS = ["", "nan", "NaN", "inf", "-inf", "1e308", "-1e400", "1e400", "abc", "²", "1,5", " 7.2 ", "0x10", "-999",
         "1e-400", "9" * 400, "١٢", "10.5.3", "+", "-", "1_000", "−3", "\x00", "7.2\x00", "True", "1j", "11.2", "0"]
TIMES = ["", "10-11-2010", "2010-13-45T00:00Z", "2262-04-12T00:00Z", "9999-01-01", "1677-09-21T00:00Z",
         "2010-10-18T00:00+14:00", "2010-10-18T00:00-12:00", "2010-10-18T25:00", "abc", "2010-10-18T00:00:00.5Z",
         "1e10", "0", "2010-W42-1", "20101018", "2010-10-18 00:00", "1970-01-01", "2200-01-01T00:00Z"]
NAMES = ["", "A", ".h", "A.x", "Z.h", "A.h", "B.h", "A.Q", "time", "A.h ", "a.h", "A.h_up", "A..h", "x" * 100_000]
EVENT = {"date": ["2010-13-01", "10-11-2010", "abc", "", "9999-01-01", "2262-04-11", "1677-09-21", "2010-10-18T00"],
         "time": ["25:00:00", "abc", "", "00:00", "00:00:00.5", "-1:00:00", "23:59:60", "12:00:00"],
         "value": CELLS, "flag": ["-1", "abc", "", "6", "3", "9223372036854775807", "0.5", "NaN", "2"]}
HEADER = ["abc", "", "1e20", "-12", "14.5", "nan", "cm", "m NAP", "Z", "A", "h", "Q", "l/s", "-999", "inf", "9" * 50]


def _line(rng: random.Random, text: str, change) -> str:
    lines = text.splitlines()
    if len(lines) > 1:
        i = rng.randrange(1, len(lines))
        lines[i] = change(lines[i])
    return "\n".join(lines) + "\n"


def _cell(rng, text):
    def change(line):
        parts = line.split(",")
        j = rng.randrange(len(parts))
        parts[j] = rng.choice(TIMES if j == 0 else CELLS)
        return ",".join(parts)
    return _line(rng, text, change)


def _header(rng, text):
    lines = text.splitlines() or [""]
    parts = lines[0].split(",")
    parts[rng.randrange(len(parts))] = rng.choice(NAMES)
    return "\n".join([",".join(parts), *lines[1:]]) + "\n"


def _duplicate(rng, text):
    lines = text.splitlines()
    i = rng.randrange(len(lines))
    return "\n".join([*lines[:i + 1], lines[i], *lines[i + 1:]]) + "\n"


def _swap(rng, text):
    lines = text.splitlines()
    if len(lines) > 2:
        i = rng.randrange(1, len(lines) - 1)
        lines[i], lines[i + 1] = lines[i + 1], lines[i]
    return "\n".join(lines) + "\n"


def _truncate(rng, text):
    return text[:rng.randrange(len(text) + 1)]


def _stray(rng, text):
    i = rng.randrange(len(text) + 1)
    stray = rng.choice(["\x00", "\ufeff", "\r", '"', "'", ";", "\t", "<", "&", "]]>", "\u2028", "💧"])
    return text[:i] + stray + text[i:]


def _column(rng, text):
    return "\n".join(line + "," + (rng.choice(NAMES) if k == 0 else rng.choice(CELLS))
                     for k, line in enumerate(text.splitlines())) + "\n"


def _scale(rng, text):
    factor = rng.choice([100.0, 1000.0, -1.0, 0.0, 3.28, 1e6, 1e-3])
    lines = text.splitlines()
    out = lines[:1]
    for line in lines[1:]:
        parts = line.split(",")
        out.append(",".join([parts[0], *(f"{float(x) * factor:.6f}" if _number(x) else x for x in parts[1:])]))
    return "\n".join(out) + "\n"


def _long(rng, text):
    return _line(rng, text, lambda line: line + "," + "7" * rng.choice([10**3, 10**5]))


def _delimiter(rng, text):
    return text.replace(",", rng.choice([";", "\t", " ", ", "]))


def _empty(rng, text):
    return rng.choice(["", "\n", "time\n", "time,A.h\n", "\ufeff", "time,A.h\n2010-10-18T00:00Z\n"])


def _crlf(rng, text):
    return text.replace("\n", "\r\n")


def _event_attribute(rng, text):
    events = list(re.finditer(r"<event [^>]*/>", text))
    if not events:
        return text
    m = rng.choice(events)
    name = rng.choice(list(EVENT))
    value = rng.choice(EVENT[name]).replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;")
    event = m.group(0)
    changed = (re.sub(f'{name}="[^"]*"', f'{name}="{value}"', event) if f'{name}="' in event else
               event.replace("/>", f' {name}="{value}"/>'))
    return text[:m.start()] + changed + text[m.end():]


def _header_element(rng, text):
    tag = rng.choice(["timeZone", "missVal", "units", "locationId", "parameterId", "type"])
    return re.sub(f"<{tag}>[^<]*</{tag}>", f"<{tag}>{rng.choice(HEADER)}</{tag}>", text, count=rng.choice([0, 1]))


def _drop_element(rng, text):
    tag = rng.choice(["header", "event", "series", "timeZone", "locationId", "parameterId", "missVal", "units"])
    return re.sub(f"<{tag}[^>]*/>|<{tag}[^>]*>.*?</{tag}>", "", text, count=1, flags=re.S)


def _prolog(rng, text):
    i = text.index("?>") + 2 if "?>" in text else 0
    return text[:i] + rng.choice(['<!DOCTYPE x [<!ENTITY a "b">]>', "<!-- c -->", "<?pi x?>"]) + text[i:]


def _namespace(rng, text):
    return text.replace("http://www.wldelft.nl/fews/PI", rng.choice(["", "x", "http://other"]))


CSV_MUTATIONS = [_cell, _header, _duplicate, _swap, _truncate, _stray, _column, _scale, _long, _delimiter, _empty,
                 _crlf]
XML_MUTATIONS = [_event_attribute, _header_element, _duplicate, _drop_element, _prolog, _namespace, _swap, _truncate,
                 _stray, _empty, _long]


def _number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


@pytest.fixture(scope="module")
def world(tmp_path_factory: pytest.TempPathFactory):
    """The model, its plausible ranges and the two valid files the mutations start from."""
    model = ToyRiver()
    ranges = plausible_ranges(model, model.observables, FIRST - pd.Timedelta("8D"), FIRST + pd.Timedelta("2D"), {},
                              3600.0)
    obs = _observations(model, [], start="2010-10-17", end="2010-10-20")
    folder = tmp_path_factory.mktemp("base")
    csv_text = write_observations_csv(obs, folder / "base.csv").read_text(encoding="utf-8")
    xml_text = write_pixml(folder / "base.xml", obs.to_frame()).read_text(encoding="utf-8")
    return model, ranges, {"csv": csv_text, "xml": xml_text}


def _stored(store: Store, source: str) -> pd.DataFrame:
    """Every value the store holds from ``source``, flagged or not."""
    rows = store._conn.execute("SELECT series, time, value, flag FROM observations WHERE source = ? "
                               "ORDER BY series, time", (source,)).fetchall()
    return pd.DataFrame(rows, columns=["series", "time", "value", "flag"])


def _expected_csv(text: str) -> pd.DataFrame:
    """An independent reading of a CSV file the reader accepted: every finite number of a known column."""
    rows = list(csv.reader(io.StringIO(text.lstrip("\ufeff"))))
    header = [h.strip() for h in rows[0]]
    out = []
    for row in rows[1:]:
        cells = [(name, cell) for name, cell in zip(header[1:], row[1:], strict=False)
                 if name in ("A.h", "B.h") and cell.strip()]
        if not cells:
            continue
        time = datetime.fromisoformat(row[0].strip().replace("Z", "+00:00"))
        time = time.replace(tzinfo=UTC) if time.tzinfo is None else time.astimezone(UTC)
        for name, cell in cells:
            if math.isfinite(float(cell)):
                out.append((name, int(time.timestamp()), float(cell)))
    return pd.DataFrame(sorted(out), columns=["series", "time", "value"])


@pytest.mark.parametrize("kind", ["csv", "xml"])
def test_every_mutated_observation_file_is_stored_right_or_refused_cleanly(world, tmp_path: Path, kind: str) -> None:
    model, ranges, base = world
    rng = random.Random(f"observation-fuzz-{kind}")
    mutations = CSV_MUTATIONS if kind == "csv" else XML_MUTATIONS
    internal, unclear, wrong, outcomes = [], [], [], {"stored": 0, "refused": 0}
    with Store(":memory:") as store:
        for k in range(CASES):
            text = base[kind]
            applied = [rng.choice(mutations) for _ in range(rng.randint(1, 3))]
            for mutate in applied:
                text = mutate(rng, text)
            path = tmp_path / f"delivery-{k}.{kind}"
            path.write_text(text, encoding="utf-8", errors="surrogatepass")
            what = f"case {k} ({', '.join(m.__name__ for m in applied)})"
            try:
                ingest_file(store, path, model, ranges)
            except CaseError as exc:
                outcomes["refused"] += 1
                message = str(exc)
                if path.name not in message or len(message) > 3000 or "Traceback" in message:
                    unclear.append(f"{what}: {message[:300]!r}")
                if len(_stored(store, path.name)):
                    wrong.append(f"{what}: refused, but {len(_stored(store, path.name))} values were stored")
                continue
            except Exception as exc:  # every other exception is what the test looks for
                internal.append(f"{what}: {type(exc).__name__}: {str(exc)[:300]}")
                continue
            outcomes["stored"] += 1
            got = _stored(store, path.name)
            if kind == "csv":
                want = _expected_csv(text)
                same = (len(got) == len(want) and (got["series"].to_numpy() == want["series"].to_numpy()).all()
                        and (got["time"].to_numpy() == want["time"].to_numpy()).all()
                        and np.allclose(got["value"].to_numpy(float), want["value"].to_numpy(float), rtol=1e-12))
                if not same:
                    wrong.append(f"{what}: stored {len(got)} values, the file holds {len(want)}")
            else:
                values = {float(v) for v in re.findall(r'value="([^"]*)"', text) if _number(v)}
                if len(got) == 0 or not set(got["value"].astype(float)) <= values:
                    wrong.append(f"{what}: stored values that are not the file's events' values")
            for sid in ("A.h", "B.h"):  # whatever lies outside the plausible range is stored as an outlier
                ok = got[(got["series"] == sid) & (got["flag"] == "ok")]["value"]
                if ((ok < ranges[sid].low) | (ok > ranges[sid].high)).any():
                    wrong.append(f"{what}: an implausible value of {sid} is stored as ok")
    assert not internal, f"{len(internal)} internal errors:\n" + "\n".join(internal[:10])
    assert not unclear, f"{len(unclear)} unclear messages:\n" + "\n".join(unclear[:10])
    assert not wrong, f"{len(wrong)} wrong results:\n" + "\n".join(wrong[:10])
    assert outcomes["stored"] > CASES // 10 and outcomes["refused"] > CASES // 2, outcomes  # both ways exercised
