"""A Delft-FEWS module folder for the tests of ``rivercal fews``, laid out from the how-to's example.

The example's run file (``docs/howto/example-fews/run_info.xml``: CET, paths relative to its folder) is copied
into a fresh folder with observations FEWS would have exported (PI-XML in CET, written with plain
``xml.etree``): the packaged case ``dommel`` simulated with a bed friction of 25 m^(1/3)/s where the case has 16,
so that a cycle's estimate has a known answer. ``quick`` properties (FA only, a two-day window, a six-hour
forecast) keep a whole cycle under a second or two.
"""

from __future__ import annotations

import functools
import os
import shutil
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "docs" / "howto" / "example-fews"
NS = "http://www.wldelft.nl/fews/PI"
ZONE_H = 1.0  # the example's run file is in CET
T0 = pd.Timestamp("2010-11-07T00:00Z")  # the example's time0 (01:00 CET)
TRUE_FA = 25.0  # the friction the observations were simulated with (the case's own is 16)
#: Properties that make one cycle cheap (the example's own run a 7-day window, two parameters, 48 h ahead).
QUICK = {"parameters": "FA", "window": "1D", "warmup": "3h", "horizon": "3h", "deadline": "60"}


def q(tag: str) -> str:
    """A tag in the PI namespace."""
    return f"{{{NS}}}{tag}"


@functools.cache
def observed() -> pd.DataFrame:
    """Hourly levels and discharges of ``dommel`` with bed friction 25, 2010-11-01 .. 2010-11-09 UTC (m, m³/s)."""
    from rivercal.model import load_model

    result, _ = load_model("dommel").simulate({"friction:global": TRUE_FA}, "2010-10-28", "2010-11-09")
    return result.series.loc["2010-11-01":]


def _local(t: pd.Timestamp) -> dict[str, str]:
    loc = (t + pd.Timedelta(hours=ZONE_H)).tz_localize(None)
    return {"date": loc.strftime("%Y-%m-%d"), "time": loc.strftime("%H:%M:%S")}


def export_series(path: Path, frame: pd.DataFrame, *, units: dict[str, str] | None = None,
                  miss: float = -999.0) -> Path:
    """FEWS's export: one ``<series>`` per column ``<location>.<parameter>``, CET, ``missVal`` for NaN."""
    ET.register_namespace("", NS)
    root = ET.Element(q("TimeSeries"), version="1.2")
    ET.SubElement(root, q("timeZone")).text = f"{ZONE_H:.1f}"
    for col in frame.columns:
        loc, _, par = str(col).rpartition(".")
        s = ET.SubElement(root, q("series"))
        h = ET.SubElement(s, q("header"))
        for tag, text in (("type", "instantaneous"), ("locationId", loc), ("parameterId", par)):
            ET.SubElement(h, q(tag)).text = text
        ET.SubElement(h, q("timeStep"), unit="second", multiplier="3600")
        ET.SubElement(h, q("startDate"), _local(frame.index[0]))
        ET.SubElement(h, q("endDate"), _local(frame.index[-1]))
        ET.SubElement(h, q("missVal")).text = str(miss)
        ET.SubElement(h, q("units")).text = (units or {}).get(str(col), "m3/s" if par == "Q" else "m")
        for t, v in frame[col].items():
            ET.SubElement(s, q("event"), {**_local(t), "value": str(miss if np.isnan(v) else round(float(v), 6)),
                                          "flag": "0"})
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path


def module(folder: Path, *, quick: bool = True, observations: bool = True) -> Path:
    """A module folder from the example (its run file, ``quick`` properties), observations in ``input/``."""
    shutil.copytree(EXAMPLE, folder)
    run_file = folder / "run_info.xml"
    if quick:
        set_properties(run_file, **QUICK)
    if observations:
        export_series(folder / "input" / "observations.xml", observed().loc[T0 - pd.Timedelta("3D"):T0])
    return run_file


def _tree(run_file: Path) -> ET.ElementTree:
    ET.register_namespace("", NS)
    return ET.parse(run_file)


def set_properties(run_file: Path, **values: str) -> Path:
    """Set (or add) ``<string>`` properties of a run file; a value None removes the property."""
    tree = _tree(run_file)
    props = tree.getroot().find(q("properties"))
    for key, value in values.items():
        node = next((n for n in props if n.get("key") == key), None)
        if node is None and value is not None:
            node = ET.SubElement(props, q("string"), key=key)
        if value is None:
            if node is not None:
                props.remove(node)
        else:
            node.set("value", value)
    tree.write(run_file, encoding="UTF-8", xml_declaration=True)
    return run_file


def set_element(run_file: Path, tag: str, text: str | None = None, **attrs: str) -> Path:
    """Set the text or attributes of the run file's first ``tag`` (added before ``properties`` if missing)."""
    tree = _tree(run_file)
    root = tree.getroot()
    node = root.find(q(tag))
    if node is None:
        node = ET.Element(q(tag))
        root.insert(list(root).index(root.find(q("properties"))), node)
    if text is not None:
        node.text = text
    for key, value in attrs.items():
        node.set(key, value)
    tree.write(run_file, encoding="UTF-8", xml_declaration=True)
    return run_file


def add_element(run_file: Path, tag: str, text: str) -> Path:
    """Add a ``tag`` element after the run file's last one (or before ``properties``)."""
    tree = _tree(run_file)
    root = tree.getroot()
    children = list(root)
    same = [i for i, node in enumerate(children) if node.tag == q(tag)]
    at = same[-1] + 1 if same else children.index(root.find(q("properties")))
    node = ET.Element(q(tag))
    node.text = text
    root.insert(at, node)
    tree.write(run_file, encoding="UTF-8", xml_declaration=True)
    return run_file


def state_description(path: Path, read: str, write: str) -> Path:
    """A PI state description as FEWS exports it: one file location."""
    ET.register_namespace("", NS)
    root = ET.Element(q("State"), version="1.2")
    ET.SubElement(root, q("stateId")).text = "rivercal"
    ET.SubElement(root, q("timeZone")).text = f"{ZONE_H:.1f}"
    ET.SubElement(root, q("dateTime"), _local(T0 - pd.Timedelta("1D")))
    loc = ET.SubElement(root, q("stateLoc"), type="file")
    ET.SubElement(loc, q("readLocation")).text = read
    ET.SubElement(loc, q("writeLocation")).text = write
    path.parent.mkdir(parents=True, exist_ok=True)
    ET.ElementTree(root).write(path, encoding="UTF-8", xml_declaration=True)
    return path


def hand_over_state(run_file: Path, read: str, write: str) -> Path:
    """FEWS hands a state over: a description in ``input/state.xml`` named by the run file."""
    description = state_description(run_file.parent / "input" / "state.xml", read, write)
    set_element(run_file, "inputStateDescriptionFile", "input/state.xml")
    return description


def diag_lines(path: Path) -> list[tuple[int, str]]:
    """(level, text) of a PI diagnostics file, read with plain ``xml.etree``."""
    return [(int(n.get("level")), n.get("description")) for n in ET.parse(path).getroot().findall(q("line"))]


def snapshot(folder: Path) -> dict[str, tuple[int, int, bytes]]:
    """Every file under ``folder`` (relative name -> size, mtime in ns, first 64 bytes), to compare before/after."""
    out = {}
    for path in sorted(folder.rglob("*")):
        if path.is_file() and not path.is_symlink():
            st = path.stat()
            with path.open("rb") as f:
                out[str(path.relative_to(folder))] = (st.st_size, st.st_mtime_ns, f.read(64))
    return out


class FileAudit:
    """What the process does to files while it is active, from Python's audit events (``sys.addaudithook``).

    ``writes``: paths opened for writing, created, removed, renamed or copied to, and databases SQLite opened;
    ``reads``: paths opened for reading or copied from. Events of every thread are seen; only one audit is active at
    a time (a hook cannot be removed, so one hook serves every audit of the session).
    """

    _active: FileAudit | None = None
    _installed = False

    def __init__(self) -> None:
        self.writes: list[Path] = []
        self.reads: list[Path] = []

    @classmethod
    def _hook(cls, event: str, args: tuple) -> None:
        audit = cls._active
        if audit is None:
            return
        if event == "open" and args and isinstance(args[0], (str, bytes, Path)):
            path, mode, flags = args[0], args[1], args[2] if len(args) > 2 else 0
            writing = (isinstance(mode, str) and any(c in mode for c in "wax+")) or (
                isinstance(flags, int) and flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND))
            (audit.writes if writing else audit.reads).append(Path(os.fsdecode(path)))
        elif event == "sqlite3.connect" and args:
            audit.writes.append(Path(str(args[0])))
        elif event in ("os.remove", "os.mkdir", "os.rmdir", "os.symlink", "os.truncate") and args:
            if isinstance(args[0], (str, bytes, Path)):
                audit.writes.append(Path(str(args[0])))
        elif event == "os.rename" and len(args) >= 2:
            audit.writes.extend(Path(str(a)) for a in args[:2])
        elif event in ("shutil.copyfile", "shutil.copymode", "shutil.copystat") and len(args) >= 2:
            audit.reads.append(Path(str(args[0])))
            audit.writes.append(Path(str(args[1])))

    def __enter__(self) -> FileAudit:
        if not FileAudit._installed:
            sys.addaudithook(FileAudit._hook)
            FileAudit._installed = True
        FileAudit._active = self
        return self

    def __exit__(self, *exc: object) -> None:
        FileAudit._active = None

    def touched(self, folder: Path) -> list[Path]:
        """Every path under ``folder`` (symbolic links followed) that was read or written."""
        root = folder.resolve()
        return [p for p in self.reads + self.writes if _resolve(p).is_relative_to(root)]


def _resolve(path: Path) -> Path:
    try:
        return path.resolve()
    except (OSError, RuntimeError):
        return path.absolute()


@functools.cache
def previous_state() -> bytes:
    """The store a quick cycle issued one day before :data:`T0` hands on (its bytes): history for a hot start."""
    import tempfile

    from rivercal.fews import run_module

    with tempfile.TemporaryDirectory() as tmp:
        run_file = module(Path(tmp) / "m")
        local = (T0 - pd.Timedelta("1D") + pd.Timedelta(hours=ZONE_H)).tz_localize(None)
        set_element(run_file, "time0", date=local.strftime("%Y-%m-%d"), time=local.strftime("%H:%M:%S"))
        outcome = run_module(run_file)
        assert outcome.exit_code == 0, outcome.diagnostics
        return Path(outcome.summary["state"]).read_bytes()
