"""Where the Delft-FEWS module keeps its state and writes its outputs, checked before anything is written.

The state (a rivercal store) lies inside the module's work folder; an existing state file must be a rivercal
store, an existing output file a PI file of its kind: rivercal never reads or replaces any other file.
"""

from __future__ import annotations

import shutil
import stat
from pathlib import Path

from rivercal.fews.pi import Diagnostics, RunFile, StateLocation, read_state_description, replace_atomically
from rivercal.fews.properties import AdapterError, prop
from rivercal.io.pixml import PI_NAMESPACE

_SQLITE_MAGIC = b"SQLite format 3\x00"


def _inside_work(path: Path, run: RunFile, file: Path, field: str) -> Path:
    """``path`` (symbolic links followed), refused unless it lies inside the module's work folder."""
    try:
        resolved, work = path.resolve(), run.work_dir.resolve()
    except (OSError, RuntimeError) as exc:  # a loop of symbolic links
        raise AdapterError(f"state location {path} cannot be resolved ({exc})", file=str(file), field=field) from None
    if resolved == work:
        raise AdapterError(f"state location {path} is the module's work folder itself; rivercal's state is one file in "
                           "it", file=str(file), field=field)
    if not resolved.is_relative_to(work):
        raise AdapterError(f"state location {path} lies outside the module's work folder {work}; rivercal reads and "
                           "writes its state only inside the work folder (the run file's workDir)", file=str(file),
                           field=field)
    return resolved


def _is_store(path: Path) -> bool:
    """Whether a regular file starts as a rivercal store does (SQLite header, rivercal's application id)."""
    from rivercal.store.schema import APPLICATION_ID

    with path.open("rb") as f:
        head = f.read(100)
    return len(head) == 100 and head.startswith(_SQLITE_MAGIC) and int.from_bytes(head[68:72], "big") == APPLICATION_ID


def _check_store(path: Path, file: Path, field: str, role: str) -> None:
    """Refuse ``path`` unless it is a regular file holding a rivercal store (read, never written)."""
    what = path_kind(path)
    if what != "file":
        raise AdapterError(f"{role} {path} {PATH_KIND_WORDS.get(what, what)}", file=str(file), field=field)
    try:
        ok = _is_store(path)
    except OSError as exc:
        raise AdapterError(f"{role} {path} cannot be read ({exc.strerror or exc})", file=str(file),
                           field=field) from None
    if not ok:
        raise AdapterError(f"{role} {path} is not a rivercal store (an SQLite file that rivercal wrote); rivercal "
                           "neither reads nor replaces any other file", file=str(file), field=field)


#: How messages say what :func:`path_kind` found.
PATH_KIND_WORDS = {"missing": "does not exist", "not a file": "exists but is not a file"}


def path_kind(path: Path) -> str:
    """``file``, ``missing``, ``not a file`` (a folder, a FIFO, a device), or why ``path`` cannot be used."""
    try:
        mode = path.stat().st_mode
    except (FileNotFoundError, NotADirectoryError):
        try:
            return "is a symbolic link to nothing" if path.is_symlink() else "missing"
        except OSError as exc:
            return f"cannot be used ({exc.strerror or exc})"
    except (OSError, ValueError) as exc:  # a loop of links, a name too long, no permission
        return f"cannot be used ({getattr(exc, 'strerror', None) or exc})"
    return "file" if stat.S_ISREG(mode) else "not a file"


def _exists(path: Path) -> bool:
    return path_kind(path) != "missing"


def state_locations(run: RunFile) -> tuple[Path | None, StateLocation]:
    """(the state file FEWS handed over or None, where this run writes the state), both checked.

    Both lie inside the work folder; each that exists is a rivercal store. Nothing is opened for writing here.
    """
    if len(run.input_state_files) > 1:
        raise AdapterError(f"{len(run.input_state_files)} state descriptions; rivercal's state is one file, described "
                           "once", file=str(run.path), field="inputStateDescriptionFile")
    for description in run.input_state_files:
        what = path_kind(description)
        if what != "file":
            raise AdapterError(f"input state description {description} {PATH_KIND_WORDS.get(what, what)}",
                               file=str(run.path), field="inputStateDescriptionFile")
        _, locations = read_state_description(description, run.work_dir)
        if len(locations) > 1:
            raise AdapterError(f"{len(locations)} state locations; rivercal's state is one file", file=str(description),
                               field="stateLoc")
        loc = locations[0]
        if loc.type != "file":
            raise AdapterError(f"state location {loc.read} is a {loc.type}; rivercal's state is one file",
                               file=str(description), field="stateLoc")
        read = _inside_work(loc.read, run, description, "stateLoc/readLocation")
        write = _inside_work(loc.write, run, description, "stateLoc/writeLocation")
        if _exists(loc.read):
            _check_store(loc.read, description, "stateLoc/readLocation", "the state handed over")
        if write != read and _exists(loc.write):
            _check_store(loc.write, description, "stateLoc/writeLocation", "the state's write location")
        return (loc.read if _exists(loc.read) else None), loc
    text = prop(run, "stateFile")
    default = run.work_dir / text
    _inside_work(default, run, run.path, "properties/stateFile")
    if _exists(default):
        _check_store(default, run.path, "properties/stateFile", "the state file")
    return (default if _exists(default) else None), StateLocation(default, default)


def open_state(handed: Path | None, loc: StateLocation, diag: Diagnostics) -> Path:
    """Copy the handed-over store to the write location (a new store when there is none); both checked before."""
    loc.write.parent.mkdir(parents=True, exist_ok=True)
    sidecars = [Path(f"{loc.write}{suffix}") for suffix in ("-wal", "-shm")]
    if handed is None:
        for path in [loc.write, *sidecars]:  # an earlier store there (checked): FEWS asked for a cold start
            path.unlink(missing_ok=True)
        diag.add("info", f"no state handed over: a new state (store) at {loc.write}; the model starts cold")
    elif handed.resolve() != loc.write.resolve():
        for path in sidecars:  # the journal of an earlier store there must not meet the copy
            path.unlink(missing_ok=True)
        replace_atomically(loc.write, lambda part: shutil.copyfile(handed, part))
    return loc.write


def check_outputs(run: RunFile, loc: StateLocation) -> None:
    """Before anything is written: every output location can be written and replaces no file of another kind.

    An existing output file must be a PI file of its kind (the output of an earlier run) or empty; no output may
    be an input, the state, or another output.
    """
    outputs = [("outputDiagnosticFile", run.output_diagnostic_file, "Diag")]
    if run.output_state_file is not None:
        outputs.append(("outputStateDescriptionFile", run.output_state_file, "State"))
    outputs += [("outputTimeSeriesFile", f, "TimeSeries") for f in run.output_series_files[:2]]
    taken = {_resolved(p): what for p, what in [(run.path, "the run file"), (loc.read, "the state handed over"),
                                               (loc.write, "the state's write location"),
                                               *[(p, "an input state description") for p in run.input_state_files],
                                               *[(p, "an input time-series file") for p in run.input_series_files]]}
    for tag, path, root in outputs:
        key = _resolved(path)
        if key in taken:
            raise AdapterError(f"{path} is also {taken[key]}", file=str(run.path), field=tag)
        taken[key] = f"the {tag}"
        problem = output_problem(path, root)
        if problem:
            raise AdapterError(problem, file=str(run.path), field=tag)


def output_problem(path: Path, root: str) -> str | None:
    """Why the PI file ``path`` (root element ``root``) cannot be written, or None; creates the folder of a new one."""
    try:
        what = path_kind(path)
        if what != "missing":
            if what != "file":
                return f"{path} {PATH_KIND_WORDS.get(what, what)}"
            if not _is_pi(path, root):
                return (f"{path} exists and is not a PI <{root}> file; rivercal replaces only the output of an earlier "
                        "run")
            with path.open("ab"):
                pass
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            with path.open("xb"):
                pass
            path.unlink()
    except OSError as exc:
        return f"{path} cannot be written ({exc.strerror or exc})"
    return None


def _resolved(path: Path) -> Path:
    try:
        return path.resolve()
    except (OSError, RuntimeError):
        return path.absolute()


def _is_pi(path: Path, root: str) -> bool:
    """Whether a file is empty or its root element is the PI element ``root`` (only its start is read)."""
    import defusedxml
    import defusedxml.ElementTree as SafeET

    with path.open("rb") as f:  # not the size: files of /proc say 0 and are not empty
        if not f.read(1):
            return True
    try:
        for _, element in SafeET.iterparse(str(path), events=("start",), forbid_dtd=True):
            return bool(element.tag == f"{{{PI_NAMESPACE}}}{root}")
    except (SafeET.ParseError, defusedxml.DefusedXmlException, OSError, UnicodeError):
        return False
    return False
