"""The D-HYDRO import on damaged models: nothing is dropped silently, and a bad value is an error at its line.

Every test damages one file of the small test model (tests/dhydro_models.py) the way a real model gets
damaged, and checks what the import does: a missing or unreadable file that holds hydraulics is a
refusal naming it (the import stops unless partial imports are allowed); a value that is nonsense is an
error naming the source file, its line and key, whatever the options; never an internal error, and
never a message that blames the import for the model's values.
"""

from __future__ import annotations

import re
import shutil
import tomllib
from pathlib import Path

import pytest

from rivercal.errors import CaseError
from rivercal.io.dhydro import ImportOptions, import_dhydro
from tests.dhydro_models import write_model


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> Path:
    return write_model(tmp_path_factory.mktemp("dhydro") / "model").parent


def _model(base: Path, tmp_path: Path) -> Path:
    shutil.copytree(base, tmp_path / "model")
    return tmp_path / "model"


def _edit(path: Path, pattern: str, replacement: str) -> int:
    """Replace the first match of a (multi-line) pattern; returns the 1-based line of the change."""
    text = path.read_text(encoding="utf-8")
    m = re.search(pattern, text, flags=re.I | re.M)
    assert m, f"{pattern!r} not in {path.name}"
    path.write_text(text[:m.start()] + m.expand(replacement) + text[m.end():], encoding="utf-8")
    return text[:m.start()].count("\n") + 1


def _line_of(path: Path, pattern: str) -> int:
    text = path.read_text(encoding="utf-8")
    m = re.search(pattern, text, flags=re.I | re.M)
    assert m, f"{pattern!r} not in {path.name}"
    return text[:m.start()].count("\n") + 1


def _import(model: Path, tmp_path: Path, **options):
    return import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(realtime_lateral=0.01, **options))


def _error(model: Path, tmp_path: Path, **options) -> str:
    with pytest.raises(CaseError) as info:
        _import(model, tmp_path, **options)
    message = str(info.value)
    assert "bug" not in message and "case.toml" not in message.replace(str(tmp_path / "case"), "")
    assert not (tmp_path / "case" / "case.toml").exists()  # no case that would run without what failed
    return message


# -- files that are missing, outside the folder, unreadable or not INI -------------------------------------


def test_a_missing_structure_file_is_a_refusal_that_stops_the_import(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (model / "structures.ini").unlink()
    message = _error(model, tmp_path)
    assert "structures.ini" in message and "does not exist" in message and "--allow-partial" in message
    result = _import(model, tmp_path, allow_partial=True)  # the user may still want the rest
    assert result.ledger.status_of("file", "structures.ini") == "refused"
    assert result.summary["structures"] == {} and result.summary["refused"] >= 1


def test_a_structure_file_outside_the_model_folder_is_not_read(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    outside = tmp_path / "elsewhere.ini"
    shutil.copy(model / "structures.ini", outside)  # a valid file: refused for where it is, not for what it holds
    _edit(model / "test.mdu", r"^(structureFile\s*=\s*)\S+", r"\g<1>../elsewhere.ini")
    message = _error(model, tmp_path)
    assert "elsewhere.ini" in message and "outside the model folder" in message
    _edit(model / "test.mdu", r"^(structureFile\s*=\s*)\S+", r"\g<1>/etc/passwd")
    message = _error(model, tmp_path)
    assert "/etc/passwd" in message and "outside the model folder" in message
    assert "root:" not in (tmp_path / "case" / "import.md").read_text(encoding="utf-8")


def test_a_file_that_is_not_ini_is_refused_by_name(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (model / "structures.ini").write_text("root:x:0:0:root:/root:/bin/bash\ndaemon:x:1:1\n", encoding="utf-8")
    message = _error(model, tmp_path)
    assert "structures.ini" in message and "not a D-Flow FM structures file" in message


def test_a_missing_forcing_file_refuses_each_boundary_and_lateral_it_feeds(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (model / "boundaries.bc").unlink()
    message = _error(model, tmp_path)
    assert "boundaries.bc does not exist" in message
    result = _import(model, tmp_path, allow_partial=True)
    for kind, name in (("boundary", "A"), ("boundary", "D"), ("boundary", "E"), ("lateral", "lat_series")):
        assert result.ledger.status_of(kind, name) == "refused"
    assert result.ledger.status_of("lateral", "lat_const") == "exact"  # the others are converted


def test_a_nan_in_a_forcing_table_is_an_error_at_its_line(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "boundaries.bc", r"^(\s*360\.0\s+)6\.0", r"\g<1>nan")
    message = _error(model, tmp_path, allow_partial=True)  # an error, not a refusal: partial imports do not pass it
    assert f"boundaries.bc, line {line}" in message and "'A'" in message and "finite" in message


def test_an_infinite_value_in_a_forcing_table_is_an_error_at_its_line(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "boundaries.bc", r"^(\s*720\.0\s+)0\.3", r"\g<1>-inf")
    message = _error(model, tmp_path)
    assert f"boundaries.bc, line {line}" in message and "lat_series" in message


def test_a_truncated_network_file_is_an_error_naming_it(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    data = (model / "net.nc").read_bytes()
    for cut in (len(data) // 2, 3000, 200):
        (model / "net.nc").write_bytes(data[:cut])
        message = _error(model, tmp_path)
        assert "net.nc" in message


# -- values ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("file", "pattern", "value", "key", "problem"), [
    ("crsdef.ini", r"^(\s*levels\s*=\s*)-1\.0", "nan", "levels", "not a finite number"),
    ("crsloc.ini", r"^(\s*chainage\s*=\s*)0\.0", "-500", "chainage", "cannot be negative"),
    ("crsloc.ini", r"^(\s*shift\s*=\s*)0\.0", "nan", "shift", "not a finite number"),
    ("structures.ini", r"^(\s*crestLevel\s*=\s*)0\.3", "nan", "crestLevel", "not a finite number"),
    ("structures.ini", r"^(\s*crestLevel\s*=\s*)-0\.2", "1e6", "crestLevel", "not a plausible level"),
    ("structures.ini", r"^(\s*crestWidth\s*=\s*)4\.0", "-5", "crestWidth", "cannot be negative"),
    ("structures.ini", r"^(\s*crestWidth\s*=\s*)4\.0", "wide", "crestWidth", "valid number"),
    ("crsloc.ini", r"^(\s*chainage\s*=\s*)500\.0", "5000", "chainage", "beyond the end of branch b3"),
])
def test_a_nonsense_value_is_an_error_naming_file_line_and_key(base, tmp_path, file, pattern, value, key,
                                                               problem) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / file, pattern, rf"\g<1>{value}")
    message = _error(model, tmp_path, allow_partial=True)
    assert f"{file}, line {line}" in message and problem in message
    assert key in message or "chainage" in message


def test_reversed_zw_levels_are_an_error_not_a_one_centimetre_profile(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "crsdef.ini", r"^(\s*levels\s*=\s*)-1\.0\s+0\.0\s+2\.0", r"\g<1>2.0 0.0 -1.0")
    message = _error(model, tmp_path)
    assert f"crsdef.ini, line {line}" in message and "'zw1'" in message and "rise" in message


def test_total_widths_below_the_flow_widths_are_an_error_not_lost_storage(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "crsdef.ini", r"^(\s*totalWidths\s*=\s*)4\.0\s+8\.0\s+20\.0", r"\g<1>4.0 5.0 6.0")
    message = _error(model, tmp_path)
    assert f"crsdef.ini, line {line}" in message and "below the flow width" in message


def test_a_bad_reference_date_is_an_error_at_its_line(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "test.mdu", r"^(refDate\s*=\s*)\d+", r"\g<1>20101345")
    message = _error(model, tmp_path)
    assert f"line {line}, [Time] refDate = 20101345" in message and "test.mdu" in message


def test_a_garbage_settings_file_is_an_error_at_its_line(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (model / "rivercal.ini").write_text("[engine]\ntheta = 0.8\nstructureLength = banana\ndt = -4\n",
                                        encoding="utf-8")
    message = _error(model, tmp_path)
    assert "rivercal.ini, line 3: structureLength = banana" in message
    (model / "rivercal.ini").write_text("[engine]\ntheta = 7\n", encoding="utf-8")
    assert "rivercal.ini, line 2: theta = 7" in _error(model, tmp_path)


# -- keys -----------------------------------------------------------------------------------------------


def test_a_key_given_twice_takes_the_first_value_as_d_flow_fm_does(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "test.mdu", r"^(\[Time\]\n)", r"\g<1>tStop = 3600\n") + 1
    result = _import(model, tmp_path, allow_partial=True)
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    assert data["case"]["end"] == "2020-01-01T01:00:00Z"  # the first tStop, 3600 s
    warning = next(w for w in result.ledger.warnings if "more than once" in w)
    assert f"line {line} (tStop = 3600)" in warning and "test.mdu" in warning


def test_a_key_given_twice_in_a_block_file_takes_the_first_value(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    _edit(model / "structures.ini", r"^(\s*crestWidth\s*=\s*4\.0.*\n)", r"    crestWidth = 6.0\n\g<1>")
    result = _import(model, tmp_path, allow_partial=True)
    data = tomllib.loads((tmp_path / "case" / "case.toml").read_text(encoding="utf-8"))
    assert next(w for w in data["weirs"] if w["id"] == "weir1")["crest_width"] == 6.0
    assert any("structures.ini" in w and "crestWidth more than once" in w for w in result.ledger.warnings)


def test_an_unknown_key_is_a_warning_with_its_file_and_line(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    line = _edit(model / "test.mdu", r"^(\[Time\]\n)", r"\g<1>fooBar = 3\n") + 1
    result = _import(model, tmp_path, allow_partial=True)
    assert any(f"fooBar (line {line})" in w and "test.mdu" in w for w in result.ledger.warnings)


def test_text_that_is_not_ini_is_an_error_at_its_line(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    # a line cut short
    line = _edit(model / "structures.ini", r"^([ \t]*crestWidth[ \t]*=[ \t]*4\.0.*)$", r"    crestWid")
    message = _error(model, tmp_path)
    assert f"structures.ini, line {line}" in message and "'crestWid' is not INI text" in message


# -- the case folder ------------------------------------------------------------------------------------


def test_the_case_folder_must_be_new_empty_or_an_earlier_import(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    (tmp_path / "file").write_text("mine", encoding="utf-8")
    with pytest.raises(CaseError, match=r"--out.*exists and is not a folder"):
        import_dhydro(model / "test.mdu", tmp_path / "file")
    (tmp_path / "folder").mkdir()
    (tmp_path / "folder" / "notes.csv").write_text("mine", encoding="utf-8")
    with pytest.raises(CaseError, match=r"--out.*other files"):
        import_dhydro(model / "test.mdu", tmp_path / "folder")
    assert (tmp_path / "folder" / "notes.csv").read_text(encoding="utf-8") == "mine"  # nothing of the user's lost
    _import(model, tmp_path, allow_partial=True)
    _import(model, tmp_path, allow_partial=True)  # an earlier import's folder is replaced


def test_options_are_checked(base, tmp_path) -> None:
    model = _model(base, tmp_path)
    with pytest.raises(CaseError, match="--realtime-lateral"):
        import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(realtime_lateral=float("nan")))
    with pytest.raises(CaseError, match=r"--dt.*does not divide"):
        import_dhydro(model / "test.mdu", tmp_path / "case", ImportOptions(realtime_lateral=0.01, dt=7.0))
