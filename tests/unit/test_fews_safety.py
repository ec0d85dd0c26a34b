"""``rivercal fews`` with hostile or broken input: no file outside its place is read or written, nothing is lost.

Each test lays out a module folder from the how-to's example (:mod:`tests.fews_support`), changes one thing as a
careless configuration or a hostile one would, and runs the module in this process (:func:`run_module`, what
``rivercal fews`` runs). Python's audit events record every file the run opens, copies, renames or removes.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import pandas as pd
import pytest

from rivercal.fews import run_module
from rivercal.store import Store
from tests.fews_support import (
    T0,
    TRUE_FA,
    FileAudit,
    add_element,
    diag_lines,
    export_series,
    hand_over_state,
    module,
    observed,
    set_element,
    set_properties,
    snapshot,
)

#: A system file's stand-in beside the module folder: a regression must never get the machine's own to damage.
PASSWD_TEXT = "root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n"


def _passwd(tmp_path: Path) -> Path:
    path = tmp_path / "etc" / "passwd"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(PASSWD_TEXT, encoding="utf-8")
    return path


def _errors(outcome) -> list[str]:
    return [line.text for line in outcome.diagnostics if line.level <= 1]


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _store(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with Store(path):
        pass
    return path


def _assert_refused(outcome, *words: str) -> str:
    assert outcome.exit_code == 2, outcome.diagnostics
    errors = _errors(outcome)
    assert len(errors) == 1 and all(w in errors[0] for w in words), errors
    assert not any(line.level == 0 for line in outcome.diagnostics)  # never an internal error
    return errors[0]


# -- state write location ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("handed", ["nothing", "a store"])
def test_a_write_location_holding_another_file_is_refused_and_left_as_it_was(tmp_path: Path, handed: str) -> None:
    """FEWS's state description names a text file as the state's write location: refused, never overwritten."""
    folder = tmp_path / "m"
    run_file = module(folder, observations=False)
    victim = folder / "victim.txt"
    victim.write_text("field notes, not a store\n", encoding="utf-8")
    read = "nothere.sqlite" if handed == "nothing" else _store(folder / "state" / "exported.sqlite").name
    hand_over_state(run_file, f"state/{read}" if handed != "nothing" else read, "victim.txt")
    before = snapshot(folder)
    with FileAudit() as audit:
        outcome = run_module(run_file)
    _assert_refused(outcome, "input/state.xml: stateLoc/writeLocation:", "victim.txt is not a rivercal store")
    assert victim.read_text(encoding="utf-8") == "field notes, not a store\n"
    assert not [p for p in audit.writes if p.resolve() == victim.resolve()]
    after = snapshot(folder)
    assert {k: v for k, v in after.items() if k != "output/diag.xml"} == before  # only the diagnostics are new
    assert any("victim.txt" in text for level, text in diag_lines(folder / "output" / "diag.xml") if level == 1)


@pytest.mark.parametrize("role", ["readLocation", "writeLocation"])
@pytest.mark.parametrize("how", ["absolute", "dot-dot", "symbolic link"])
def test_a_state_location_outside_the_work_folder_is_refused(tmp_path: Path, role: str, how: str) -> None:
    """Outside the work folder nothing is read or written, not even a rivercal store."""
    folder, outside = tmp_path / "m", tmp_path / "outside"
    run_file = module(folder, observations=False)
    elsewhere = _store(outside / "elsewhere.sqlite")
    target = elsewhere if role == "readLocation" else outside / "new.sqlite"
    if how == "absolute":
        text = str(target)
    elif how == "dot-dot":
        text = f"../outside/{target.name}"
    else:
        (folder / "link.sqlite").symlink_to(target)
        text = "link.sqlite"
    read, write = (text, "state/rivercal.sqlite") if role == "readLocation" else ("state/rivercal.sqlite", text)
    hand_over_state(run_file, read, write)
    before = snapshot(outside)
    with FileAudit() as audit:
        outcome = run_module(run_file)
    _assert_refused(outcome, f"stateLoc/{role}:", "lies outside the module's work folder")
    assert snapshot(outside) == before and not (outside / "new.sqlite").exists()
    assert audit.touched(outside) == []
    assert not (folder / "state" / "rivercal.sqlite").exists()


# -- state read location and the stateFile property -----------------------------------------------------------------


def test_a_read_location_that_is_not_a_store_is_refused_before_anything_is_copied(tmp_path: Path) -> None:
    folder = tmp_path / "m"
    run_file = module(folder, observations=False)
    (folder / "state").mkdir()
    (folder / "state" / "exported.sqlite").write_text(PASSWD_TEXT, encoding="utf-8")
    hand_over_state(run_file, "state/exported.sqlite", "state/rivercal.sqlite")
    with FileAudit() as audit:
        outcome = run_module(run_file)
    _assert_refused(outcome, "stateLoc/readLocation:", "exported.sqlite is not a rivercal store")
    assert not (folder / "state" / "rivercal.sqlite").exists()  # check first, copy never
    assert not [p for p in audit.writes if p.parent.name == "state"]


def test_a_system_file_as_read_location_is_neither_read_nor_copied(tmp_path: Path) -> None:
    """``/etc/passwd`` as the state handed over (here a stand-in at ``<tmp>/etc/passwd``): refused, never opened."""
    folder, passwd = tmp_path / "m", _passwd(tmp_path)
    run_file = module(folder, observations=False)
    hand_over_state(run_file, str(passwd), "state/rivercal.sqlite")
    with FileAudit() as audit:
        outcome = run_module(run_file)
    _assert_refused(outcome, "stateLoc/readLocation:", "etc/passwd lies outside the module's work folder")
    assert passwd not in audit.reads + audit.writes and passwd.read_text(encoding="utf-8") == PASSWD_TEXT
    assert not (folder / "state").exists()


@pytest.mark.parametrize("value", ["../../../../etc/passwd", "absolute", "notes.txt"])
def test_the_state_file_property_is_confined_and_never_opened_unless_a_store(tmp_path: Path, value: str) -> None:
    """Without a state description the store is the ``stateFile`` property's file: it too is checked first.

    The module folder lies four levels below ``tmp_path``, so ``../../../../etc/passwd`` reaches the stand-in
    ``<tmp>/etc/passwd`` as it would reach the machine's own from a module folder four levels below ``/``.
    """
    folder, passwd = tmp_path / "a" / "b" / "c" / "m", _passwd(tmp_path)
    state_file = str(passwd) if value == "absolute" else value
    run_file = set_properties(module(folder, observations=False), stateFile=state_file)
    (folder / "notes.txt").write_text("not a store\n", encoding="utf-8")
    notes = _digest(folder / "notes.txt")
    with FileAudit() as audit:
        outcome = run_module(run_file)
    words = ("run_info.xml: properties/stateFile:",
             "is not a rivercal store" if value == "notes.txt" else "lies outside the module's work folder")
    _assert_refused(outcome, *words)
    assert not [p for p in audit.writes if p.resolve() in (passwd, (folder / "notes.txt").resolve())]
    assert not [p for p in audit.writes if str(p).endswith(("-wal", "-shm", "-journal"))]
    assert passwd.read_text(encoding="utf-8") == PASSWD_TEXT and _digest(folder / "notes.txt") == notes
    assert sorted(p.name for p in passwd.parent.iterdir()) == ["passwd"]  # no journal beside it


# -- times and flags that used to end in an internal error ----------------------------------------------------------


@pytest.mark.parametrize(("zone", "time0", "end"), [("1.0", ("9999-11-07", "01:00:00"), ("9999-11-09", "01:00:00")),
                                                    ("-12", ("2262-04-11", "12:00:00"), ("2262-04-11", "13:00:00"))])
def test_a_time0_rivercal_cannot_represent_is_a_clean_error(tmp_path: Path, zone: str, time0, end) -> None:
    run_file = module(tmp_path / "m", observations=False)
    set_element(run_file, "timeZone", zone)
    set_element(run_file, "time0", date=time0[0], time=time0[1])
    set_element(run_file, "endDateTime", date=end[0], time=end[1])
    outcome = run_module(run_file)
    _assert_refused(outcome, "run_info.xml: time0:", "lies outside the years 1678-2261")


@pytest.mark.parametrize(("properties", "time0", "words"), [
    ({"horizon": "40D"}, None, ("properties: property 'horizon' 40D: the cycle, issued at 2010-11-07 00:00, would "
                                "forecast to 2010-12-17 00:00, after the end of the case (2010-12-01 00:00)",
                                "the horizon can be 1h to 24D, or issue the cycle at 2010-10-22 00:00 or earlier")),
    ({"period": "5D"}, None, ("properties: property 'window' 1D: with the warm-up (3h) shorter than the cycle "
                              "(property 'period' 5D)", "lengthen property 'warmup' to 4D or more")),
    ({}, ("2010-11-07", "01:30:00"), ("time0: time0 2010-11-07 00:30: cycles are issued on the service's time step",
                                      "check the run file's timeZone, +1 h")),
])
def test_times_that_do_not_fit_the_case_are_refused_as_the_command_line_refuses_them(tmp_path: Path, properties,
                                                                                     time0, words) -> None:
    run_file = module(tmp_path / "m")
    set_properties(run_file, **properties)
    if time0 is not None:
        set_element(run_file, "time0", date=time0[0], time=time0[1])
    _assert_refused(run_module(run_file), *words)


@pytest.mark.parametrize(("flag", "value"), [("100000000000000000000", None), ("²", None), ("0", "9999-01-01")])
def test_a_flag_or_date_out_of_range_in_the_observations_names_the_file_and_series(tmp_path: Path, flag: str,
                                                                                   value: str | None) -> None:
    folder = tmp_path / "m"
    run_file = module(folder)
    path = folder / "input" / "observations.xml"
    text = path.read_text(encoding="utf-8")
    first = text.index('flag="0"')
    text = text[:first] + f'flag="{flag}"' + text[first + len('flag="0"'):]
    if value:  # the first event's date
        start = text.index('<event date="') + len('<event date="')
        text = text[:start] + value + text[start + 10:]
    path.write_text(text, encoding="utf-8")
    outcome = run_module(run_file)
    error = _assert_refused(outcome, "observations.xml", "series locationId=")
    assert ("is not a FEWS flag" in error) if not value else ("outside the years 1678-2261" in error)
    assert "invalid literal" not in error and "int()" not in error


# -- messages -------------------------------------------------------------------------------------------------------


def test_a_unit_rivercal_cannot_convert_is_explained_for_a_fews_user(tmp_path: Path) -> None:
    folder = tmp_path / "m"
    run_file = module(folder, observations=False)
    frame = observed().loc[T0 - pd.Timedelta("3D"):T0]
    export_series(folder / "input" / "observations.xml", frame, units={frame.columns[0]: "ft"})
    outcome = run_module(run_file)
    error = _assert_refused(outcome, "observations.xml", f"parameterId={frame.columns[0].rpartition('.')[2]}",
                            "unit 'ft'", "let FEWS convert it on export")
    assert "conversions=" not in error and "STANDARD_CONVERSIONS" not in error and "pass " not in error


def test_levels_in_centimetres_are_converted(tmp_path: Path) -> None:
    """A unit the file declares and rivercal knows is converted: the estimate is the true friction."""
    folder = tmp_path / "m"
    run_file = module(folder, observations=False)
    frame = observed().loc[T0 - pd.Timedelta("3D"):T0]
    levels = [c for c in frame.columns if not c.endswith(".Q")]
    in_cm = frame.copy()
    in_cm[levels] *= 100.0
    export_series(folder / "input" / "observations.xml", in_cm, units=dict.fromkeys(levels, "cm"))
    outcome = run_module(run_file)
    assert outcome.exit_code == 0, outcome.diagnostics
    assert outcome.summary["estimates"]["FA"] == pytest.approx(TRUE_FA, abs=0.5)


@pytest.mark.parametrize("output", ["outputDiagnosticFile", "outputTimeSeriesFile"])
def test_an_unwritable_output_is_found_before_the_state_advances(tmp_path: Path, output: str) -> None:
    folder = tmp_path / "m"
    run_file = module(folder)
    (folder / "blocker").write_text("a file where the module expects a folder\n", encoding="utf-8")
    set_element(run_file, output, "blocker/out.xml")
    outcome = run_module(run_file)
    error = _assert_refused(outcome, f"run_info.xml: {output}:", "blocker/out.xml cannot be written")
    assert "Not a directory" in error or "cannot be written" in error
    assert not (folder / "state").exists()  # no store: the cycle never started
    if output == "outputDiagnosticFile":
        assert outcome.diag_file is None
    else:
        assert diag_lines(folder / "output" / "diag.xml")[-1][0] == 1


def test_an_output_that_would_replace_another_file_is_refused(tmp_path: Path) -> None:
    folder = tmp_path / "m"
    run_file = module(folder)
    (folder / "case-notes.txt").write_text("keep me\n", encoding="utf-8")
    set_element(run_file, "outputTimeSeriesFile", "case-notes.txt")
    outcome = run_module(run_file)
    _assert_refused(outcome, "outputTimeSeriesFile:", "case-notes.txt exists and is not a PI <TimeSeries> file")
    assert (folder / "case-notes.txt").read_text(encoding="utf-8") == "keep me\n"
    assert not (folder / "state").exists()


def test_a_diagnostics_file_that_names_another_file_is_not_overwritten_even_when_the_run_file_is_broken(
        tmp_path: Path) -> None:
    folder = tmp_path / "m"
    run_file = module(folder, observations=False)
    (folder / "keep.txt").write_text("keep me\n", encoding="utf-8")
    set_element(run_file, "outputDiagnosticFile", "keep.txt")
    set_element(run_file, "timeZone", "CET")  # the run file cannot be read: only its diagnostics file is known
    outcome = run_module(run_file)
    assert outcome.exit_code == 2 and outcome.diag_file is None
    assert (folder / "keep.txt").read_text(encoding="utf-8") == "keep me\n"
    assert any("keep.txt exists and is not a PI <Diag> file" in text for text in _errors(outcome))


# -- forcing and workers --------------------------------------------------------------------------------------------


def _forcing(folder: Path, values) -> Path:
    from rivercal.case import load_case
    from rivercal.hydrology.catchments import catchment_forcing

    own = catchment_forcing(load_case("dommel"))["boundary:Q_ZL1_up"].loc["2010-11-04":"2010-11-08"]
    frame = pd.DataFrame({"Q_ZL1_up.Q": values(own.to_numpy())}, index=own.index)
    path = export_series(folder / "input" / "forcing.xml", frame)
    add_element(folder / "run_info.xml", "inputTimeSeriesFile", "input/forcing.xml")
    return path


@pytest.mark.parametrize(("values", "shown"), [(lambda v: v * 0 - 1e6, "-1e+06"), (lambda v: v * 0 - 50.0, "-50"),
                                               (lambda v: v * 1000.0, "")])
def test_implausible_forcing_is_refused_before_the_state_is_touched(tmp_path: Path, values, shown: str) -> None:
    """Minus a million m³/s (or an inflow turned outflow, or l/s given as m³/s) is not a forecast: an error."""
    folder = tmp_path / "m"
    run_file = module(folder)
    _forcing(folder, values)
    outcome = run_module(run_file)
    error = _assert_refused(outcome, "forcing.xml: series locationId=Q_ZL1_up parameterId=Q: forcing " + shown,
                            "lies outside the plausible range", "boundary:Q_ZL1_up")
    assert "unit or sign-convention error" in error
    assert not (folder / "state").exists()


def test_plausible_forcing_replaces_the_case_own(tmp_path: Path) -> None:
    """FEWS's forcing equal to the case's own runoff: accepted, used, and the estimate is the true friction."""
    folder = tmp_path / "m"
    run_file = module(folder)
    _forcing(folder, lambda v: v)
    outcome = run_module(run_file)
    assert outcome.exit_code == 0, outcome.diagnostics
    assert any("forcing from FEWS at boundary:Q_ZL1_up" in line.text for line in outcome.diagnostics)
    assert outcome.summary["estimates"]["FA"] == pytest.approx(TRUE_FA, abs=0.5)


@pytest.mark.parametrize("value", ["many", "0", "1.5", "-2", "cores+1", "cores*8"])
def test_the_workers_property_is_a_whole_number_up_to_the_cores(tmp_path: Path, value: str) -> None:
    """More workers than cores are refused with the limit (no process is started); nonsense too."""
    from rivercal.evaluate import default_workers

    cores = default_workers()
    value = {"cores+1": str(cores + 1), "cores*8": str(cores * 8)}.get(value, value)
    run_file = set_properties(module(tmp_path / "m"), workers=value)
    before = {child.pid for child in _children()}
    _assert_refused(run_module(run_file), "run_info.xml: properties: property 'workers'", f"from 1 to {cores}")
    assert {child.pid for child in _children()} == before
    assert not (tmp_path / "m" / "state").exists()


def _children():
    import multiprocessing

    return multiprocessing.active_children()


@pytest.mark.parametrize("what", ["constant setting", "time step"])
def test_a_setting_the_case_holds_constant_and_a_time_step_off_the_model_s_are_refused(tmp_path: Path,
                                                                                      what: str) -> None:
    """A crest FEWS gives for a weir whose crest is a constant (a calibration parameter) in the case, and a
    ``timeStep`` that is not a whole number of the model's own 60 s, are errors naming them; nothing runs."""
    folder = tmp_path / "m"
    run_file = module(folder)
    if what == "constant setting":
        frame = pd.DataFrame({"ZL1-5.crestLevel": 14.0}, index=observed().loc[T0 - pd.Timedelta("3D"):T0].index)
        export_series(folder / "input" / "settings.xml", frame)
        add_element(run_file, "inputTimeSeriesFile", "input/settings.xml")
        words = ("settings.xml: series locationId=ZL1-5 parameterId=crestLevel", "the weir ZL1-5 has a constant "
                 "crestLevel in the case")
    else:
        set_properties(run_file, timeStep="90s")
        words = ("property 'timeStep': '90s' (90 s) is not a whole multiple of the model's time step (60 s)",)
    _assert_refused(run_module(run_file), *words)
    assert not (folder / "state").exists()


def test_written_files_are_readable_as_the_umask_allows(tmp_path: Path) -> None:
    """Delft-FEWS may read the module's exports as another user: a file written atomically gets the umask's
    permissions (0644 under umask 022), not the owner-only 0600 of a temporary file, and a replaced file too."""
    import os
    import stat

    from rivercal.fews.pi import replace_atomically

    target = tmp_path / "output" / "levels.xml"
    target.parent.mkdir()
    old = os.umask(0o022)
    try:
        replace_atomically(target, lambda part: part.write_text("first", encoding="utf-8"))
        assert stat.S_IMODE(target.stat().st_mode) == 0o644
        replace_atomically(target, lambda part: part.write_text("second", encoding="utf-8"))
        assert stat.S_IMODE(target.stat().st_mode) == 0o644 and target.read_text(encoding="utf-8") == "second"
    finally:
        os.umask(old)
    assert [p.name for p in target.parent.iterdir()] == ["levels.xml"]  # no temporary file left
