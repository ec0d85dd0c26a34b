"""Fuzzed Delft-FEWS input: every case ends in a correct result or a clean error, touching nothing else.

Two surfaces, each a seeded generator of cases (reproducible: a failing case names its seed):

- **run files**, mutated from the how-to's example: elements removed, doubled or given hostile text (paths out of
  the folder, a system file — a stand-in ``passwd`` beside the folder, never the machine's own —, ``/proc``, a
  FIFO, a symbolic-link loop, dates rivercal cannot hold, time zones, numbers that are none), property values
  (durations, parameters, workers, the state file), unknown properties and files, truncated XML, a DTD;
- **PI inputs**: the exported observations and forcing (values, flags, dates, units, missing values, headers,
  repeated times, time zones), the state description and the state file FEWS hands over (locations inside and
  outside the work folder, foreign files, a damaged store), and a PI parameter file rivercal does not read.

Each case runs :func:`run_module` (what ``rivercal fews`` runs) in this process, in a fresh module folder beside a
folder ``outside`` that holds a text file and a rivercal store. Every case must end

- in exit 0 with outputs that validate against the PI schemas and equal the state's store (and, for the mutations
  that do not change what was observed, the true friction), or
- in exit 2 (bad input) or 3 (a failed model run) with an error line that names the file — never a fatal line,
  an internal error or a traceback;

and in both cases (checked with Python's audit events, and by comparing the folders before and after): no file is
written outside the module folder except the outputs the run file names, nothing in ``outside`` is read unless the
run file itself names it, no file that was there before is changed except the state and the outputs, and no
process is left behind.
"""

from __future__ import annotations

import os
import random
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import defusedxml.ElementTree as SafeET
import pandas as pd
import pytest

from rivercal.fews import run_module
from rivercal.store import Store
from tests.fews_support import NS, TRUE_FA, FileAudit, module, previous_state, q, snapshot

N_RUN_FILES = 24
N_PI_INPUTS = 24
SEED = 20101107

#: Hostile or careless texts for any element or property (the module folder is the work folder, ``..`` its parent).
PATHS = ["../outside/victim.txt", "../outside/store.sqlite", "../outside/new.xml", "{outside}/victim.txt",
         "{outside}/new.sqlite", "{outside}/passwd", "../outside/passwd", "/proc/self/status", "notes.txt",
         "input/observations.xml", "state/rivercal.sqlite", ".", "input", "", " ", "x" * 300, "no/such/folder/file.xml",
         "loop", "link-out", "fifo", "output/other.xml"]
NUMBERS = ["0", "-1", "1", "2", "1.5", "nan", "inf", "-inf", "1e308", "1e-300", "²", "1,5", "0x10", "", "many"]
DURATIONS = ["2D", "1D", "12h", "6h", "90min", "0", "0h", "-1D", "1000000D", "100000D", "P1D", "7 days", "1e400D",
             "nan", ""]
DATES = ["9999-11-07", "0001-01-01", "2262-04-11", "1677-09-21", "2010-13-01", "2010-02-30", "2010-11-07T", "",
         "2010-11-06", "2010-11-08", "2010-09-01", "2010-12-31", "20101107"]
TIMES = ["01:00:00", "25:00:00", "24:00:00", "00:00", "1:2:3", "", "01:00:00.5", "01:00:00+05:00", "23:59:59"]
ZONES = ["1.0", "0", "14", "-12", "15", "-13", "5.5", "nan", "1e308", "CET", ""]
PROPERTY_VALUES = {
    "case": ["dommel", "synthetic", "nosuchcase", "../outside", "/etc", "input", ""],
    "parameters": ["FA", "FA,Wd", "Wd", "FA,FA", "XX", "", ",", "FA;Wd", "W1,Wc"],
    "window": DURATIONS, "horizon": DURATIONS, "warmup": DURATIONS, "period": DURATIONS,
    "algorithm": ["dud", "trf", "nelder_mead", "nosuch", ""],
    "deadline": NUMBERS, "alertK": NUMBERS, "workers": [*NUMBERS, "3", "16", "64"],
    "maxChange": ["FA=5", "FA=", "=5", "FA=-1", "FA=nan", "XX=1", "FA=5,FA=6", "FA==3", ""],
    "run": ["fews", "", "x" * 300, "a/b", "'; DROP TABLE runs;--"],
    "stateFile": PATHS, "estimatesLocationId": ["dommel", "", "x" * 300, "<&>"],
    "piSchemaDir": ["", "{schemas}", "input", "/etc", "../outside"],
}
UNUSED_FILES = ["inputParameterFile", "inputNetcdfFile", "outputNetcdfFile", "inputMapStackFile"]


@dataclass
class Case:
    """One fuzz case: the module folder, the folder beside it, and what the mutation promised."""

    folder: Path
    outside: Path
    neutral: bool  # the mutation does not change what was observed: the estimate must be the true friction
    note: str


def _layout(tmp_path: Path) -> Case:
    folder, outside = tmp_path / "m", tmp_path / "outside"
    run_file = module(folder)
    outside.mkdir()
    (outside / "victim.txt").write_text("someone's notes\n", encoding="utf-8")
    (outside / "passwd").write_text("root:x:0:0:root:/root:/bin/bash\n", encoding="utf-8")  # never the real one
    with Store(outside / "store.sqlite"):
        pass
    (folder / "notes.txt").write_text("the modeller's notes\n", encoding="utf-8")
    (folder / "loop").symlink_to(folder / "loop")
    (folder / "link-out").symlink_to(outside / "victim.txt")
    os.mkfifo(folder / "fifo")
    assert run_file.is_file()
    return Case(folder, outside, True, "")


def _text(rng: random.Random, pool: list[str], case: Case) -> str:
    from tests.conftest import PI_SCHEMA_DIR

    return rng.choice(pool).format(outside=case.outside, schemas=PI_SCHEMA_DIR)


# -- run-file mutations ------------------------------------------------------------------------------------------------


def _mutate_run_file(rng: random.Random, case: Case) -> None:
    path = case.folder / "run_info.xml"
    ET.register_namespace("", NS)
    tree = ET.parse(path)
    root = tree.getroot()
    notes, raw = [], None
    for _ in range(rng.randint(1, 3)):
        kind = rng.choice(["drop", "double", "text", "date", "zone", "property", "property", "property", "unknown",
                           "unused", "raw", "neutral"])
        children = [c for c in root if c.tag != q("properties")]
        props = root.find(q("properties"))
        if kind == "drop":
            node = rng.choice(children + ([props] if props is not None else []))
            root.remove(node)
            notes.append(f"drop {node.tag}")
        elif kind == "double":
            node = rng.choice(children)
            copy = ET.Element(node.tag, node.attrib)
            copy.text = _text(rng, PATHS, case) if rng.random() < 0.5 else node.text
            root.insert(list(root).index(node) + 1, copy)
            notes.append(f"double {node.tag}: {copy.text!r}")
        elif kind == "text":
            node = rng.choice([c for c in children if not c.attrib] or children)
            node.text = _text(rng, PATHS + NUMBERS, case)
            notes.append(f"{node.tag} = {node.text!r}")
        elif kind == "date":
            node = root.find(q(rng.choice(["time0", "startDateTime", "endDateTime"])))
            if node is not None:
                node.set("date", rng.choice(DATES))
                node.set("time", rng.choice(TIMES))
                notes.append(f"{node.tag} = {node.attrib}")
        elif kind == "zone":
            node = root.find(q("timeZone"))
            if node is not None:
                node.text = rng.choice(ZONES)
                notes.append(f"timeZone = {node.text!r}")
        elif kind == "property" and props is not None:
            key = rng.choice(sorted(PROPERTY_VALUES))
            value = _text(rng, PROPERTY_VALUES[key], case)
            node = next((n for n in props if n.get("key") == key), None)
            if node is None:
                node = ET.SubElement(props, q("string"), key=key)
            node.set("value", value)
            notes.append(f"property {key} = {value!r}")
        elif kind == "unknown" and props is not None:
            ET.SubElement(props, q(rng.choice(["string", "int", "bool"])), key=rng.choice(["paramters", "window", ""]),
                          value="1")
            notes.append("unknown or doubled property")
        elif kind == "unused":
            node = ET.Element(q(rng.choice(UNUSED_FILES)))
            node.text = _text(rng, PATHS, case)
            root.insert(list(root).index(props) if props is not None else len(root), node)
            notes.append(f"unused {node.tag}")
        elif kind == "raw":
            raw = rng.choice(["truncate", "dtd", "root", "namespace"])
            notes.append(f"raw {raw}")
        else:
            notes.append("neutral: a comment")
            root.insert(0, ET.Comment("exported by FEWS"))
            continue
        case.neutral = False
    tree.write(path, encoding="UTF-8", xml_declaration=True)
    if raw == "truncate":
        data = path.read_bytes()
        path.write_bytes(data[:rng.randint(0, len(data) - 1)])
    elif raw == "dtd":
        text = path.read_text(encoding="utf-8").replace(
            "?>", '?>\n<!DOCTYPE Run [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">'
                  f'<!ENTITY x SYSTEM "file://{case.outside}/victim.txt">]>', 1)
        path.write_text(text.replace("<workDir>.</workDir>", "<workDir>&b;&x;</workDir>"), encoding="utf-8")
    elif raw == "root":
        path.write_text(path.read_text(encoding="utf-8").replace("<Run ", "<State ").replace("</Run>", "</State>"),
                        encoding="utf-8")
    elif raw == "namespace":
        path.write_text(path.read_text(encoding="utf-8").replace(NS, "http://example.org/not-pi"), encoding="utf-8")
    case.note = "; ".join(notes)


# -- PI input mutations ------------------------------------------------------------------------------------------------

VALUES = ["", "nan", "NaN", "inf", "-inf", "1e400", "abc", "²", "1,5", " 7.3 ", "-999", "-999.0", "0x10", "1e6", "-1e6",
          "1e-320", "7"]
FLAGS = ["", "-1", "²", "1e20", "100000000000000000000", "2147483648", "6", "9", "3", "0.5", " 2 ", "0"]
UNITS = ["cm", "mm", "ft", "", "m NAP", "metre", "m3/s", "l/s", "K"]
LOCATIONS = ["0028", "NOPE", "", "Q_ZL1_up", "L_C01", "ZL1_outflow", "0029"]
PARAMETERS = ["h", "h_up", "Q", "WQ", "H.meting", ""]


def _mutate_series(rng: random.Random, case: Case, path: Path) -> list[str]:
    tree = ET.parse(path)
    root = tree.getroot()
    series = root.findall(q("series"))
    notes = []
    kind = rng.choice(["value", "flag", "date", "no-date", "header", "units", "missval", "zone", "repeat", "drop",
                       "empty", "forcing", "neutral-missing", "neutral-unreliable", "neutral-units",
                       "neutral-comment"])
    s = rng.choice(series)
    events = s.findall(q("event"))
    header = s.find(q("header"))
    event = rng.choice(events) if events else None
    if kind.startswith("neutral"):
        if kind == "neutral-missing" and event is not None:
            event.set("value", "-999")  # missVal: dropped, as when the telemetry missed a value
        elif kind == "neutral-unreliable" and event is not None:
            event.set("flag", "6")
        elif kind == "neutral-units":
            header.find(q("units")).text = "m NAP" if header.findtext(q("parameterId")) != "Q" else "m3 s-1"
        else:
            root.insert(0, ET.Comment("exported by FEWS"))
        notes.append(kind)
    else:
        case.neutral = False
        if kind == "value" and event is not None:
            event.set("value", rng.choice(VALUES))
        elif kind == "flag" and event is not None:
            event.set("flag", rng.choice(FLAGS))
        elif kind == "date" and event is not None:
            event.set(rng.choice(["date", "time"]), rng.choice(DATES + TIMES))
        elif kind == "no-date" and event is not None:
            del event.attrib[rng.choice(["date", "time"])]
        elif kind == "header":
            tag = rng.choice(["locationId", "parameterId"])
            node = header.find(q(tag))
            node.text = rng.choice(LOCATIONS if tag == "locationId" else PARAMETERS)
        elif kind == "units":
            header.find(q("units")).text = rng.choice(UNITS)
        elif kind == "missval":
            header.find(q("missVal")).text = rng.choice(["nan", "abc", "", "7.3", "1e400"])
        elif kind == "zone":
            root.find(q("timeZone")).text = rng.choice(ZONES)
        elif kind == "repeat" and event is not None:
            s.insert(list(s).index(event) + 1, ET.Element(event.tag, dict(event.attrib)))
        elif kind == "drop":
            root.remove(s)
        elif kind == "empty":
            for e in events:
                s.remove(e)
        elif kind == "forcing":  # the series becomes forcing at the upstream boundary, scaled
            header.find(q("locationId")).text = "Q_ZL1_up"
            header.find(q("parameterId")).text = "Q"
            header.find(q("units")).text = "m3/s"
            factor = rng.choice([1.0, -1.0, 1000.0, 0.5, -1e6])
            for e in events:
                e.set("value", repr(abs(float(e.get("value"))) * factor / 10.0))
        notes.append(kind)
    tree.write(path, encoding="UTF-8", xml_declaration=True)
    if rng.random() < 0.05:
        data = path.read_bytes()
        path.write_bytes(data[:rng.randint(0, len(data) - 1)])
        case.neutral = False
        notes.append("truncated")
    return notes


def _mutate_state(rng: random.Random, case: Case) -> list[str]:
    from tests.fews_support import hand_over_state

    run_file = case.folder / "run_info.xml"
    store = case.folder / "state" / "exported.sqlite"
    store.parent.mkdir(exist_ok=True)
    history = rng.random() < 0.5
    if history:  # the store a cycle one day earlier handed on: a hot start
        store.write_bytes(previous_state())
    else:  # a store without history
        with Store(store):
            pass
    damage = rng.random() < 0.2
    if damage:  # a store's header with rubbish after it
        data = store.read_bytes()
        store.write_bytes(data[:100] + bytes(rng.randrange(256) for _ in range(4000)))
    choices = ["state/exported.sqlite", "state/rivercal.sqlite", *PATHS]
    read, write = _text(rng, choices, case), _text(rng, choices, case)
    description = hand_over_state(run_file, read, write)
    notes = [f"state read {read!r} write {write!r}" + (" (damaged store)" if damage else "")
             + (" with history" if history else "")]
    if rng.random() < 0.3:
        ET.register_namespace("", NS)
        tree = ET.parse(description)
        root = tree.getroot()
        what = rng.choice(["type", "two", "none", "date"])
        loc = root.find(q("stateLoc"))
        if what == "type":
            loc.set("type", rng.choice(["directory", "", "files"]))
        elif what == "two":
            root.append(ET.fromstring(ET.tostring(loc)))
        elif what == "none":
            root.remove(loc)
        else:
            root.find(q("dateTime")).set("date", rng.choice(DATES))
        tree.write(description, encoding="UTF-8", xml_declaration=True)
        notes.append(f"state description: {what}")
    case.neutral = case.neutral and read == "state/exported.sqlite" and not damage and len(notes) == 1
    return notes


def _mutate_inputs(rng: random.Random, case: Case) -> None:
    notes = []
    surface = rng.choice(["series", "series", "series", "state", "state", "parameters"])
    if surface == "series":
        notes += _mutate_series(rng, case, case.folder / "input" / "observations.xml")
    elif surface == "state":
        notes += _mutate_state(rng, case)
    else:  # a PI parameter file rivercal does not read: a warning, the run goes on
        from tests.fews_support import add_element

        (case.folder / "input" / "params.xml").write_text("<ModelParameters/>", encoding="utf-8")
        add_element(case.folder / "run_info.xml", "inputParameterFile", _text(rng, ["input/params.xml", *PATHS], case))
        notes.append("inputParameterFile")
    case.note = "; ".join(notes)


# -- the checks --------------------------------------------------------------------------------------------------------


def _named(case: Case) -> set[Path]:
    """Every path the (mutated) run file names, as element text or property value, resolved as rivercal may."""
    run_file = case.folder / "run_info.xml"
    try:
        root = SafeET.parse(str(run_file), forbid_dtd=True).getroot()
    except Exception:  # unreadable: it names nothing
        return set()
    work = case.folder
    for node in root.iter(q("workDir")):
        if node.text and node.text.strip():
            try:
                work = (case.folder / node.text.strip()).resolve()
            except (OSError, RuntimeError):  # a loop of symbolic links
                work = case.folder / node.text.strip()
    texts = [n.text.strip() for n in root.iter() if n.text and n.text.strip()]
    texts += [n.get("value", "").strip() for n in root.iter() if n.get("key")]
    out = set()
    for text in texts:
        for base in (case.folder, work):
            try:
                out.add((base / text).resolve())
            except (OSError, RuntimeError, ValueError):
                pass
    return out


def _children() -> set[int]:
    """Processes whose parent is this one."""
    me, out = os.getpid(), set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rpartition(")")[2].split()[1]) == me:
                out.add(int(entry.name))
    return out


def _check(case: Case, outcome, audit: FileAudit, before: dict, children: set[int], pi_schema) -> None:
    why = f"case: {case.note}; diagnostics: {[(line.level, line.text[:300]) for line in outcome.diagnostics]}"
    texts = [line.text for line in outcome.diagnostics]
    assert not any(line.level == 0 for line in outcome.diagnostics), why
    assert not any("Traceback" in t or "internal error" in t or "please report" in t for t in texts), why
    assert outcome.exit_code in (0, 2, 3), why
    # files: nothing outside but what the run file names; nothing that was there changed but state and outputs
    named = _named(case)
    tmp = case.folder.parent.resolve()
    for path in audit.writes:
        p = path.resolve() if path.is_absolute() else (Path.cwd() / path).resolve()
        if p.is_relative_to(tmp) and not p.is_relative_to(case.folder.resolve()):  # a named output, its folder, or
            assert (p in named or any(n.is_relative_to(p) for n in named)  # the temporary file it is written to
                    or any(p.parent == n.parent and p.name.startswith(f".{n.name}.") for n in named)), (p, why)
        assert not str(p).startswith(("/etc/", "/proc/", "/sys/", "/dev/")) or str(p) == "/dev/null", (p, why)
    for path in audit.reads:
        p = (path if path.is_absolute() else Path.cwd() / path).resolve()
        if p.is_relative_to(case.outside.resolve()):
            assert p in named or any(p.is_relative_to(n) for n in named if n.is_dir()), (p, why)
    after = snapshot(case.folder.parent)
    for name, stamp in before.items():
        if name.startswith(("m/state/", "m/output/")) or (case.folder.parent / name).resolve() in named:
            continue
        assert after.get(name) == stamp, (name, why)
    assert (case.outside / "victim.txt").read_text(encoding="utf-8") == "someone's notes\n", why
    assert (case.outside / "passwd").read_text(encoding="utf-8") == "root:x:0:0:root:/root:/bin/bash\n", why
    assert _children() <= children, why
    if outcome.exit_code:
        errors = [line.text for line in outcome.diagnostics if line.level == 1]
        assert errors, why
        assert outcome.exit_code == 3 or any("/" in e or "property" in e for e in errors), why
        return
    _check_result(case, outcome, pi_schema, why)


def _check_result(case: Case, outcome, pi_schema, why: str) -> None:
    """An exit 0: outputs valid and equal to the store; the true friction where nothing observed was changed."""
    assert not [line for line in outcome.diagnostics if line.level <= 1], why
    summary = outcome.summary
    files = [Path(f) for f in summary["files"]]
    for f in files:
        schema = "pi_state.xsd" if ET.parse(f).getroot().tag == q("State") else "pi_timeseries.xsd"
        pi_schema(schema).validate(str(f))
    with Store(summary["state"], readonly=True) as store:
        runs = store.runs()
        run = store.get_run(runs["name"].iloc[-1]) if "name" in runs else None
        assert run is not None, why
        cycles = store.cycles(run)
        assert pd.Timestamp(summary["issue_time"]) == cycles["issue_time"].iloc[-1], why
        est = store.estimates(run)
        est = est[est["cycle"] == summary["cycle"]].set_index("parameter")["value"]
    assert {k: pytest.approx(v, rel=1e-12) for k, v in summary["estimates"].items()} == est.to_dict(), why
    estimates = [f for f in files if f.name != "state.xml"][-1]
    root = ET.parse(estimates).getroot()
    for s in root.findall(q("series")):
        h = s.find(q("header"))
        if not h.findall(q("qualifierId")) and h.findtext(q("parameterId")) in est:
            value = float(s.find(q("event")).get("value"))
            assert value == pytest.approx(est[h.findtext(q("parameterId"))], rel=1e-9), why
    if case.neutral and "FA" in summary["accepted"] and summary["status"] == "done" and "FA" not in summary["held"]:
        assert summary["estimates"]["FA"] == pytest.approx(TRUE_FA, abs=0.5), why


def _run_case(case: Case, pi_schema) -> None:
    before, children = snapshot(case.folder.parent), _children()
    with FileAudit() as audit:
        outcome = run_module(case.folder / "run_info.xml")
    _check(case, outcome, audit, before, children, pi_schema)


@pytest.mark.parametrize("k", range(N_RUN_FILES))
def test_fuzzed_run_files_end_in_a_result_or_a_clean_error(tmp_path: Path, k: int, pi_schema) -> None:
    case = _layout(tmp_path)
    _mutate_run_file(random.Random(SEED + k), case)
    _run_case(case, pi_schema)


@pytest.mark.parametrize("k", range(N_PI_INPUTS))
def test_fuzzed_pi_inputs_end_in_a_result_or_a_clean_error(tmp_path: Path, k: int, pi_schema) -> None:
    case = _layout(tmp_path)
    _mutate_inputs(random.Random(SEED + 1000 + k), case)
    _run_case(case, pi_schema)


def test_the_generators_mix_harmless_and_hostile_cases(tmp_path: Path) -> None:
    """Some cases change nothing that was observed (their estimate is checked), most are hostile (first 16 of each)."""
    neutral = []
    for k in range(16):
        case = _layout(tmp_path / f"r{k}")
        _mutate_run_file(random.Random(SEED + k), case)
        neutral.append(case.neutral)
        case = _layout(tmp_path / f"p{k}")
        _mutate_inputs(random.Random(SEED + 1000 + k), case)
        neutral.append(case.neutral)
    assert 2 <= sum(neutral) <= len(neutral) // 3, sum(neutral)
