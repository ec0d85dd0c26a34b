"""The black box keeps to its folders and reads bounded amounts; no program is run here.

Every file a ``model.toml`` names lies in the model folder (template sources) or the run folder (targets,
restart files, outputs); a name that leads elsewhere — ``..``, an absolute path, a link in the model
folder — is refused when the model is loaded, naming the file and the field, and nothing is written or
read outside. Outputs are read with bounds (file, line and value sizes) and every message quotes a short
excerpt; a time written twice, a text value, a FIFO and a dangling link each get their own message.
"""

from __future__ import annotations

import os
import re
import time
import warnings
from pathlib import Path

import pytest

from rivercal.models import load_model
from rivercal.models.blackbox.readers import MAX_LINE_BYTES, MAX_TEXT_BYTES, read_output
from rivercal.models.blackbox.runs import RunFolders, _started
from rivercal.models.config import ModelFileError
from tests.blackbox_models import make_model

HEADER = "time,level,flow\n"
SERIES = {"S.h": "level", "S.Q": "flow"}


def edit(toml: Path, old: str, new: str) -> None:
    text = toml.read_text()
    assert old in text
    toml.write_text(text.replace(old, new))


def snapshot(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


# -- paths confined, refused at load ------------------------------------------------------------------------

TEMPLATES = 'templates = [{ source = "input.json.tmpl" }]'
STATE = 'state = { restart_out = ["restart.txt"], restart_in = ["restart_in.txt"] }'
OUTPUT = 'file = "out.csv"'


@pytest.mark.parametrize(("old", "new", "field", "why"), [
    (TEMPLATES, 'templates = [{ source = "input.json.tmpl", target = "../../ESCAPE.txt" }]',
     r"blackbox\.templates\[0\]\.target", r"'\.\./\.\./ESCAPE\.txt' leads out of the run folder"),
    (TEMPLATES, 'templates = [{ source = "input.json.tmpl", target = "{tmp}/ESCAPE.txt" }]',
     r"blackbox\.templates\[0\]\.target", "is an absolute path"),
    (TEMPLATES, 'templates = [{ source = "input.json.tmpl" }, { source = "../../../../etc/passwd", target = "p" }]',
     r"blackbox\.templates\[1\]\.source", "leads out of the model folder"),
    (TEMPLATES, 'templates = [{ source = "input.json.tmpl" }, { source = "/etc/passwd", target = "p" }]',
     r"blackbox\.templates\[1\]\.source", "is an absolute path"),
    (STATE, 'state = { restart_out = ["restart.txt"], restart_in = ["../../x"] }',
     r"blackbox\.state\.restart_in\[0\]", "leads out of the run folder"),
    (STATE, 'state = { restart_out = ["/etc/passwd"], restart_in = ["restart_in.txt"] }',
     r"blackbox\.state\.restart_out\[0\]", "is an absolute path"),
    (STATE, 'state = { restart_out = ["a/restart.txt", "b/restart.txt"], restart_in = ["r1", "r2"] }',
     r"blackbox\.state\.restart_out\[1\]", "'restart.txt' is named twice"),
    (OUTPUT, 'file = "/etc/passwd"', r"blackbox\.outputs\[0\]\.file", "is an absolute path"),
    (OUTPUT, 'file = "sub/../../out.csv"', r"blackbox\.outputs\[0\]\.file", "leads out of the run folder"),
    (OUTPUT, 'file = "stderr.txt"', r"blackbox\.outputs\[0\]\.file", "where the program's output goes"),
    ('folder = "toy"', 'folder = "/"', r"blackbox\.folder", "is an absolute path"),
    ('folder = "toy"', 'folder = "../.."', r"blackbox\.folder", "leads out of the folder of model.toml"),
    ('folder = "toy"', 'folder = "to\\u0000y"', r"blackbox\.folder", "holds a NUL character"),
    ('runs_dir = "runs"', 'runs_dir = "toy"', r"blackbox\.runs_dir", "is the model folder"),
])
def test_a_file_outside_its_folder_is_refused_at_load_naming_the_field(tmp_path, old, new, field, why) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    toml = tmp_path / "m" / "model.toml"
    edit(toml, old, new.replace("{tmp}", str(tmp_path)))
    before = snapshot(tmp_path)
    with pytest.raises(ModelFileError, match=re.escape(str(toml)) + ": " + field + ": .*" + why):
        load_model(toml)
    assert snapshot(tmp_path) - before <= {"m/runs"}  # nothing written (the runs folder may be made)


@pytest.mark.parametrize(("link", "why"), [
    ("{outside}", r"is a symbolic link to .*secret\.txt, outside the model folder"),
    ("/etc", "is a symbolic link to /etc, outside the model folder"),
    ("nowhere", "is a symbolic link that dangles"),
    ("loop", "is a symbolic link that loops"),
])
def test_a_link_in_the_model_folder_that_leads_outside_dangles_or_loops_is_refused(tmp_path, link, why) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    outside = tmp_path / "secret.txt"
    outside.write_text("secret")
    (tmp_path / "m" / "toy" / "sub").mkdir()
    os.symlink(link.replace("{outside}", str(outside)), tmp_path / "m" / "toy" / "sub" / "loop")
    with pytest.raises(ModelFileError, match=r"model\.toml: blackbox\.folder: .*sub/loop " + why):
        load_model(tmp_path / "m" / "model.toml")


def test_a_template_that_is_a_link_to_a_file_outside_is_refused(tmp_path) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    template = tmp_path / "m" / "toy" / "input.json.tmpl"
    (tmp_path / "elsewhere.tmpl").write_text(template.read_text())
    template.unlink()
    template.symlink_to(tmp_path / "elsewhere.tmpl")
    with pytest.raises(ModelFileError, match=r"blackbox\.templates\[0\]\.source: .* leads outside the model folder"):
        load_model(tmp_path / "m" / "model.toml")


def test_links_inside_the_model_folder_are_copied_without_recursing(tmp_path) -> None:
    """A link to a file becomes a copy; a link to a folder, even an enclosing one, a link in the copy."""
    make_model(tmp_path / "m", runs_dir="runs")
    folder = tmp_path / "m" / "toy"
    (folder / "data").mkdir()
    (folder / "data" / "a.txt").write_text("a")
    os.symlink("data/a.txt", folder / "a-link.txt")
    os.symlink(str(folder / "data"), folder / "data-link")  # absolute, inside
    os.symlink(".", folder / "data" / "up")  # an enclosing folder: shutil.copytree would recurse 40 levels
    model = load_model(tmp_path / "m" / "model.toml")
    run_dir = model.runs.new(model.folder)
    assert (run_dir / "a-link.txt").read_text() == "a" and not (run_dir / "a-link.txt").is_symlink()
    assert os.readlink(run_dir / "data-link") == "data" and (run_dir / "data-link" / "a.txt").read_text() == "a"
    assert os.readlink(run_dir / "data" / "up") == "." and not (run_dir / "input.json.tmpl").exists()


def test_a_fifo_in_the_model_folder_is_refused(tmp_path) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    os.mkfifo(tmp_path / "m" / "toy" / "pipe")
    with pytest.raises(ModelFileError, match=r"blackbox\.folder: .*pipe is a FIFO \(named pipe\): a model folder "
                                             "holds files and folders only"):
        load_model(tmp_path / "m" / "model.toml")


def test_a_template_that_is_a_fifo_is_named_so(tmp_path) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    template = tmp_path / "m" / "toy" / "input.json.tmpl"
    template.unlink()
    os.mkfifo(template)
    with pytest.raises(ModelFileError, match=r"blackbox\.templates\[0\]\.source: the template .* is a FIFO"):
        load_model(tmp_path / "m" / "model.toml")


def test_a_runs_dir_that_cannot_hold_run_folders_is_refused_at_load(tmp_path) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    toml = tmp_path / "m" / "model.toml"
    edit(toml, 'runs_dir = "runs"', 'runs_dir = "model.toml"')
    with pytest.raises(ModelFileError, match=r"blackbox\.runs_dir: cannot hold run folders in .*model\.toml: it is "
                                             "a file, not a folder"):
        load_model(toml)
    edit(toml, 'runs_dir = "model.toml"', 'runs_dir = "model.toml/runs"')
    with pytest.raises(ModelFileError, match=r"blackbox\.runs_dir: cannot hold run folders in .*: Not a directory"):
        load_model(toml)
    edit(toml, 'runs_dir = "model.toml/runs"', 'runs_dir = "/proc/rivercal-runs"')  # not writable, even by root
    with pytest.raises(ModelFileError, match=r"blackbox\.runs_dir: cannot hold run folders in /proc/rivercal-runs"):
        load_model(toml)
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        edit(toml, 'runs_dir = "/proc/rivercal-runs"', f'runs_dir = "{locked}"')
        with pytest.raises(ModelFileError, match=r"blackbox\.runs_dir: .*Permission denied"):
            load_model(toml)


@pytest.mark.parametrize(("old", "new", "field", "why"), [
    ('format = ".6f"', 'format = "1000000000"', r"blackbox\.quantities\.crest\.format", "width or precision"),
    ('command = ["{python}", "toy.py"]', 'command = ["{python}", "toy.py", "{k:999999999}"]', r"blackbox\.command",
     "width or precision above 999"),
    ('command = ["{python}", "toy.py"]', 'command = ["{python}", "toy.py", "a\\u0000b"]',
     r"blackbox\.command\[2\]", "NUL"),
    ('env = { TOY_MODE = "" }', 'env = { "A=B" = "x" }', r"blackbox\.env\.A=B", "is not an environment variable"),
    ('env = { TOY_MODE = "" }', 'env = { A = "x\\u0000" }', r"blackbox\.env\.A", "is not an environment variable"),
])
def test_values_that_would_fail_inside_a_run_are_refused_at_load(tmp_path, old, new, field, why) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    toml = tmp_path / "m" / "model.toml"
    edit(toml, old, new)
    with pytest.raises(ModelFileError, match=r"model\.toml: " + field + ": .*" + why):
        load_model(toml)


def test_a_template_placeholder_with_a_huge_width_is_refused(tmp_path) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    (tmp_path / "m" / "toy" / "input.json.tmpl").write_text('{"k": {{k:1000000000}}}')
    with pytest.raises(ModelFileError, match=r"blackbox\.templates\[0\]: .*width or precision above 999"):
        load_model(tmp_path / "m" / "model.toml")


# -- run folders of dead processes are swept ----------------------------------------------------------------


def _dead_pid() -> int:
    pid = 4_000_000
    while Path(f"/proc/{pid}").exists():
        pid -= 1
    return pid


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="process start times come from /proc")
def test_run_folders_of_ended_processes_are_removed_when_the_model_is_loaded(tmp_path) -> None:
    make_model(tmp_path / "m", runs_dir="runs")
    runs = tmp_path / "m" / "runs"
    mine = runs / f"run-{os.getpid()}-{_started(os.getpid())}-0"  # a live run: kept
    dead = runs / f"run-{_dead_pid()}-12345-0"  # its process ended
    reused = runs / f"run-{os.getpid()}-{_started(os.getpid()) + 1}-3"  # the pid is alive, but another process's
    failed = runs / "failed-20200101T000000-1-1-0"  # kept for inspection (pruned by keep_failed)
    for folder in (mine, dead, reused, failed):
        (folder / "sub").mkdir(parents=True)
    load_model(tmp_path / "m" / "model.toml")
    assert mine.is_dir() and failed.is_dir() and not dead.exists() and not reused.exists()
    folders = RunFolders("toy", base=runs)
    assert folders.sweep() == []


# -- bounded reads, messages ---------------------------------------------------------------------------------


def _read(path: Path, text: str | None = None) -> None:
    if text is not None:
        path.write_text(text)
    read_output("csv", path, SERIES, "time", label="out.csv")


def test_a_huge_field_or_line_fails_at_once_with_a_short_message(tmp_path) -> None:
    out = tmp_path / "out.csv"
    cases = {
        "field": (HEADER + "2020-01-01T00:00:00Z,1.0,2\n2020-01-01T01:00:00Z," + "x" * 1_000_000 + ",2\n",
                  r"out\.csv line 3: column 'level' holds 'x{40}'… \(1,000,000 characters\), not a number"),
        "digits": (HEADER + "2020-01-01T00:00:00Z," + "9" * 1_000_000 + ",2\n",
                   r"out\.csv line 2: column 'level' holds '9{40}'… \(1,000,000 characters\), not a number"),
        "time": (HEADER + "2020-01-01T00:00:00Z" + "1" * 1_000_000 + ",1,2\n",
                 r"out\.csv line 2: column 'time' holds '2020.*'… \(1,000,020 characters\), not an ISO 8601 time"),
        "line": (HEADER + "2020-01-01T00:00:00Z,1.0," + "2" * (MAX_LINE_BYTES + 10) + "\n",
                 r"out\.csv: line 2 is longer than 1,048,576 bytes"),
    }
    for text, message in cases.values():
        t0 = time.perf_counter()
        with pytest.raises(ValueError, match=message) as info:
            _read(out, text)
        assert time.perf_counter() - t0 < 2.0 and len(str(info.value)) < 200
    # a 200 MB line (sparse: no disk written) and a file above the bound fail before anything is parsed
    with open(out, "wb") as f:
        f.write(HEADER.encode())
        f.truncate(200 << 20)
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match=r"out\.csv: line 2 is longer than 1,048,576 bytes"):
        _read(out)
    with open(out, "wb") as f:
        f.truncate(MAX_TEXT_BYTES + 1)
    with pytest.raises(ValueError, match=r"out\.csv holds 268,435,457 bytes, more than the 268,435,456 rivercal "
                                         "reads of a csv output"):
        _read(out)
    assert time.perf_counter() - t0 < 2.0


def test_a_text_value_a_bad_time_and_a_duplicated_time_are_named(tmp_path) -> None:
    out = tmp_path / "out.csv"
    good = "2020-01-01T00:00:00Z,1.0,2\n"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no pandas warning (or hint) reaches the user
        with pytest.raises(ValueError, match=r"^out\.csv line 3: column 'level' holds 'high', not a number$"):
            _read(out, HEADER + good + "2020-01-01T01:00:00Z,high,2\n")
        with pytest.raises(ValueError, match=r"^out\.csv line 5: column 'time' holds 'yesterday', not an ISO 8601 "
                                             r"time$"):
            _read(out, HEADER + good + "\n2020-01-01T01:00:00Z,1,2\nyesterday,1,2\n")
        with pytest.raises(ValueError, match=r"^out\.csv: the time 2020-01-01T00:00:00\+00:00 is written more than "
                                             "once"):
            _read(out, HEADER + good + "2020-01-01T01:00:00+01:00,2.0,2\n")
        with pytest.raises(ValueError, match=r"^out\.csv: line 2 holds more fields than its header$"):
            _read(out, HEADER + "2020-01-01T00:00:00Z,1,5,2\n")
        with pytest.raises(ValueError, match=r"^out\.csv: line 3 holds 4 fields, its header 3$"):
            _read(out, HEADER + good + "2020-01-01T01:00:00Z,1,5,2\n")
        frame = read_output("csv", out.write_text(HEADER + good + "2020-01-01 01:00,nan,\n") and out, SERIES)
    assert frame["S.h"].iloc[0] == 1.0 and frame["S.h"].isna().iloc[1] and frame["S.Q"].isna().iloc[1]


def test_an_output_that_is_a_fifo_or_a_dangling_link_is_named_so(tmp_path) -> None:
    os.mkfifo(tmp_path / "pipe.csv")
    with pytest.raises(ValueError, match=r"^pipe\.csv is a FIFO \(named pipe\), not a file$"):
        read_output("csv", tmp_path / "pipe.csv", SERIES, label="pipe.csv")
    os.symlink("nowhere.csv", tmp_path / "link.csv")
    with pytest.raises(ValueError, match=r"^link\.csv is a symbolic link that dangles$"):
        read_output("csv", tmp_path / "link.csv", SERIES, label="link.csv")
    with pytest.raises(ValueError, match=r"^the program wrote no none\.csv$"):
        read_output("csv", tmp_path / "none.csv", SERIES, label="none.csv")
