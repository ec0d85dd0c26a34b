"""Loading a case: a folder with ``case.toml`` and the CSV series it references.

``load_case`` accepts a folder or the name of a case shipped in the package
(``rivercal/cases/<name>/``). Every problem is raised at load time as a
:class:`~rivercal.errors.CaseError` that names the file, the field and what is wrong, so that the
engine never sees an invalid case. Messages are one line: ``<file>: <field>: <problem>``.
"""

from __future__ import annotations

import difflib
import functools
import tomllib
import types
import typing
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import pandas as pd
from pydantic import BaseModel, ValidationError

from rivercal._time import utc
from rivercal.case.schema import CaseFile
from rivercal.case.series import SeriesTable, check_coverage, check_range, read_series_table, series_column
from rivercal.errors import CaseError
from rivercal.network import MAX_DISCHARGE, MAX_LEVEL, FieldProblem, Network, SeriesRef

__all__ = ["Case", "available_cases", "case_from_dict", "load_case", "resolve_case_path"]

CASE_FILE = "case.toml"


@dataclass(frozen=True)
class Case:
    """A validated case with its forcing series loaded.

    Attributes
    ----------
    spec
        The validated ``case.toml``.
    root
        The case folder (series paths are relative to it).
    forcing
        Time series of boundaries and laterals by key ``"boundary:<id>"`` / ``"lateral:<id>"``;
        values in m³/s (discharges) or m AD (levels); UTC DatetimeIndex. Constant values are
        stored as two-point series spanning the period. Structure settings that follow a series:
        ``"crest:<weir>"`` and ``"gate:<orifice>"`` (m AD), ``"capacity:<pump>"`` (m³/s).
    """

    spec: CaseFile
    root: Path
    forcing: dict[str, pd.Series] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """Short name of the case."""
        return self.spec.case.name

    @property
    def start(self) -> pd.Timestamp:
        """Start of the simulated period (UTC)."""
        return utc(self.spec.case.start)

    @property
    def end(self) -> pd.Timestamp:
        """End of the simulated period (UTC)."""
        return utc(self.spec.case.end)

    @functools.cached_property
    def network(self) -> Network:
        """The network of this case."""
        return self.spec.network()


def available_cases() -> list[str]:
    """Names of the cases shipped inside the package."""
    base = resources.files("rivercal.cases")
    return sorted(p.name for p in base.iterdir() if p.is_dir() and (p / CASE_FILE).is_file())


def resolve_case_path(source: str | Path) -> Path:
    """The folder of a case given as a path or as the name of a packaged case.

    Raises
    ------
    CaseError
        When ``source`` is neither a case folder nor a packaged case.
    """
    path = Path(source)
    if path.is_dir():
        if not (path / CASE_FILE).is_file():
            raise CaseError(f"the folder has no {CASE_FILE}", file=str(path))
        return path
    if path.is_file() and path.name == CASE_FILE:
        return path.parent
    name = str(source)
    if name in available_cases():
        return Path(str(resources.files("rivercal.cases") / name))
    raise CaseError(
        f"{source!r} is neither a case folder nor a packaged case (packaged: {', '.join(available_cases())})"
    )


def load_case(source: str | Path) -> Case:
    """Load and validate a case.

    Parameters
    ----------
    source
        A case folder, the path of its ``case.toml``, or the name of a packaged case.

    Returns
    -------
    Case
        The validated case with its series.

    Raises
    ------
    CaseError
        Naming the file, the field and the problem.

    Examples
    --------
    >>> from rivercal.case import load_case
    >>> case = load_case("synthetic")
    >>> case.name
    'synthetic'
    """
    root = resolve_case_path(source)
    toml_path = root / CASE_FILE
    label = str(toml_path)
    try:
        data = tomllib.loads(toml_path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"not valid TOML: {_one_line(exc)}", file=label) from None
    except UnicodeDecodeError as exc:
        raise CaseError(f"not UTF-8 text: {_one_line(exc)}", file=label) from None
    except OSError as exc:
        raise CaseError(f"cannot be read: {_one_line(exc)}", file=label) from None
    return case_from_dict(data, root)


def case_from_dict(data: dict[str, Any], root: Path) -> Case:
    """Validate a parsed ``case.toml`` and load the series it references from ``root``.

    Raises
    ------
    CaseError
        Naming the file, the field and the problem.
    """
    label = str(Path(root) / CASE_FILE)
    if not isinstance(data, dict):
        raise CaseError(f"expected a table of settings, got {type(data).__name__}", file=label)
    try:
        spec = CaseFile.model_validate(data)
    except ValidationError as exc:
        raise _case_error(exc, label) from None
    except FieldProblem as exc:  # raised outside pydantic's wrapping
        raise CaseError(exc.reason, file=label, field=exc.path or None) from None
    except (ValueError, TypeError, ArithmeticError) as exc:
        raise CaseError(_one_line(exc), file=label) from None
    forcing = _load_forcing(spec, Path(root))
    if spec.meteo is not None and not (Path(root) / spec.meteo.file).is_file():
        raise CaseError(f"meteo file {spec.meteo.file!r} not found in {root}", file=str(Path(root) / CASE_FILE),
                        field="meteo.file")
    return Case(spec=spec, root=Path(root), forcing=forcing)


# -- pydantic errors → one line a water manager can act on --------------------------------------------

_TAGS = {"rectangular", "trapezoidal", "circular", "zw", "yz"}
_TAG_NAMES = "'rectangular', 'trapezoidal', 'circular', 'zw' or 'yz'"
#: The ``type`` tags of ``[[controllers]]`` (dropped from a field path right after the entry's index).
_CONTROLLER_TAGS = {"pid", "interval", "time", "relation"}
_CONTROLLER_TAG_NAMES = "'pid', 'interval', 'time' or 'relation'"


def _case_error(exc: ValidationError, label: str) -> CaseError:
    errors = exc.errors(include_url=False)
    err = errors[0]
    if err.get("type") == "missing":
        # A misspelt field shows as a missing field plus an unknown one: report the unknown one,
        # with the missing one as the suggestion.
        parent = tuple(err.get("loc", ()))[:-1]
        missing = [e for e in errors if e.get("type") == "missing" and tuple(e["loc"])[:-1] == parent]
        for other in errors:
            loc = tuple(other.get("loc", ()))
            if other.get("type") == "extra_forbidden" and loc[:-1] == parent:
                err = {**other, "ctx": {"missing": [e["loc"][-1] for e in missing]}}
                errors = [e for e in errors if e is not missing[0]]  # the misspelling and its miss are one problem
                break
    path, msg = _describe(err)
    more = len(errors) - 1
    if more:
        msg += f" (and {more} more problem{'s' if more > 1 else ''})"
    return CaseError(msg, file=label, field=path or None)


def _describe(err: dict) -> tuple[str, str]:
    """The field path and a plain-words message of one pydantic error."""
    loc = tuple(err.get("loc", ()))
    kind = err.get("type", "")
    ctx = err.get("ctx") or {}
    value = err.get("input")
    path = _format_loc(loc)
    if kind == "value_error" and isinstance(ctx.get("error"), FieldProblem):
        problem: FieldProblem = ctx["error"]
        return _join(path, problem.path), problem.reason
    if kind == "missing":
        return path, "required field is missing"
    if kind == "extra_forbidden":
        name = str(loc[-1]) if loc else ""
        missing = [str(m) for m in ctx.get("missing", [])]
        allowed = _fields_at(loc)
        guess = difflib.get_close_matches(name, missing, n=1, cutoff=0.5) or difflib.get_close_matches(
            name, allowed, n=1, cutoff=0.6
        )
        if guess:
            hint = f"; did you mean {guess[0]!r}?"
        elif allowed:
            hint = f"; the fields here are {', '.join(allowed)}"
        else:
            hint = "; see docs/case-format.md or `rivercal case schema`"
        return path, f"unknown field {name!r}{hint}"
    if kind in ("float_type", "float_parsing", "int_type", "int_parsing"):
        what = "a whole number" if kind.startswith("int") else "a number"
        extra = " (remove the quotes)" if isinstance(value, str) and _is_number(value) else ""
        return path, f"expected {what}, got {_show(value)}{extra}"
    if kind == "int_from_float":
        return path, f"expected a whole number, got {_show(value)}"
    if kind == "finite_number":
        return path, f"expected a finite number, got {_show(value)}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        words = {"greater_than": "greater than", "greater_than_equal": "at least", "less_than": "less than",
                 "less_than_equal": "at most"}[kind]
        bound = next(iter(ctx.values()), "?")
        shown = f"{bound:g}" if isinstance(bound, float | int) else str(bound)
        return path, f"must be {words} {shown}, got {_show(value)}"
    if kind == "string_pattern_mismatch":
        return path, (f"{_show(value)} is not a valid id: use only letters, digits, '_', '-' and '.' "
                      "(no spaces), at most 64 characters")
    if kind in ("string_too_short", "too_short"):
        need = ctx.get("min_length", 1)
        if kind == "string_too_short":
            return path, "must not be empty"
        return path, f"needs at least {need} entr{'y' if need == 1 else 'ies'}, got {ctx.get('actual_length', 0)}"
    if kind in ("string_too_long", "too_long"):
        return path, f"is too long (at most {ctx.get('max_length')})"
    if kind == "string_type":
        return path, f"expected text in quotes, got {_show(value)}"
    if kind == "literal_error":
        return path, f"{_show(value)} is not allowed; expected {ctx.get('expected', '?')}"
    if kind == "union_tag_invalid":
        return _join(path, "type"), f"unknown {_what(loc)} type {ctx.get('tag')!r}; expected {_tag_names(loc)}"
    if kind == "union_tag_not_found":
        return _join(path, "type"), f"the {_what(loc)} type is missing; expected {_tag_names(loc)}"
    if kind in ("model_type", "model_attributes_type", "dict_type"):
        return path, f"expected a table ({{ key = value, ... }}), got {_show(value)}"
    if kind in ("list_type", "tuple_type"):
        return path, f"expected a list ([ ... ]), got {_show(value)}"
    if kind.startswith(("datetime", "date")):
        return path, f"expected a date-time such as 2020-01-01T00:00:00Z, got {_show(value)}"
    if kind == "bool_type":
        return path, f"expected true or false, got {_show(value)}"
    msg = str(err.get("msg", "invalid value")).removeprefix("Value error, ")
    return path, " ".join(msg.split())


def _format_loc(loc: tuple) -> str:
    out = ""
    for i, part in enumerate(loc):
        if loc[0] == "controllers" and i == 2 and part in _CONTROLLER_TAGS:
            continue
        if isinstance(part, int):
            out += f"[{part}]"
        elif not isinstance(part, str) or part in _TAGS or "[" in part or "(" in part:
            continue  # discriminator tags and pydantic's internal validator names
        else:
            out += f".{part}" if out else part
    return out


def _join(base: str, rel: str) -> str:
    if not rel:
        return base
    if not base:
        return rel
    return base + rel if rel.startswith("[") else f"{base}.{rel}"


def _what(loc: tuple) -> str:
    return {"profiles": "profile", "controllers": "controller"}.get(loc[0] if loc else "", "table")


def _tag_names(loc: tuple) -> str:
    return _CONTROLLER_TAG_NAMES if loc and loc[0] == "controllers" else _TAG_NAMES


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        text = value if len(value) <= 40 else value[:37] + "..."
        return f"text {text!r}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list | tuple):
        return "a list"
    if value is None:
        return "nothing"
    if isinstance(value, float):
        return f"{value:g}"
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _fields_at(loc: tuple) -> list[str]:
    """The field names of the table that holds ``loc[-1]`` (for 'did you mean' hints)."""
    current: Any = CaseFile
    for part in loc[:-1]:
        current = _step(current, part)
        if current is None:
            return []
    models = [t for t in _alternatives(current) if isinstance(t, type) and issubclass(t, BaseModel)]
    return list(models[0].model_fields) if len(models) == 1 else []


def _alternatives(annotation: Any) -> list[Any]:
    """The types an annotation allows: Annotated, Optional and unions unwrapped."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _alternatives(typing.get_args(annotation)[0])
    if origin in (typing.Union, types.UnionType):
        return [t for arg in typing.get_args(annotation) for t in _alternatives(arg)]
    return [annotation]


def _step(annotation: Any, part: Any) -> Any:
    for t in _alternatives(annotation):
        if isinstance(part, int) and typing.get_origin(t) in (list, tuple):
            return typing.get_args(t)[0]
        if isinstance(part, str) and isinstance(t, type) and issubclass(t, BaseModel):
            tag = t.model_fields.get("type")
            if part in _TAGS | _CONTROLLER_TAGS and tag is not None and typing.get_args(tag.annotation) == (part,):
                return t
            if part in t.model_fields:
                return t.model_fields[part].annotation
    return None


# -- series ------------------------------------------------------------------------------------------


def _load_forcing(spec: CaseFile, root: Path) -> dict[str, pd.Series]:
    start, end = pd.Timestamp(spec.case.start), pd.Timestamp(spec.case.end)
    tables: dict[Path, SeriesTable] = {}
    forcing: dict[str, pd.Series] = {}
    items = [("boundaries", "boundary", i, b) for i, b in enumerate(spec.boundaries)] + [
        ("laterals", "lateral", i, lat) for i, lat in enumerate(spec.laterals)
    ]
    for table, kind, i, item in items:
        key = f"{kind}:{item.id}"
        if getattr(item, "type", None) in ("rating", "critical") or item.catchment is not None:
            continue  # no series (a table or the outfall's law), or catchment runoff computed by rivercal.hydrology
        if item.value is not None:
            forcing[key] = pd.Series([item.value, item.value], index=pd.DatetimeIndex([start, end]), name=key)
            continue
        ref: SeriesRef = item.series
        used_by = f"{table}[{i}].series of {kind} {item.id!r}"
        series = _column(root, ref, tables, field=f"{table}[{i}].series", used_by=used_by)
        check_coverage(series, start, end, file=str(root / ref.file), field=ref.column, used_by=used_by)
        is_level = getattr(item, "type", None) == "level"
        check_range(series, MAX_LEVEL if is_level else MAX_DISCHARGE, "m AD" if is_level else "m³/s",
                    file=str(root / ref.file), field=ref.column, used_by=used_by)
        series.name = key
        forcing[key] = series
    settings = [("weirs", "weir", "crest_series", "crest", True), ("orifices", "orifice", "gate_series", "gate", True),
                ("pumps", "pump", "capacity_series", "capacity", False)]
    for table, kind, name, prefix, is_level in settings:
        for i, item in enumerate(getattr(spec, table)):
            ref = getattr(item, name)
            if ref is None:
                continue
            used_by = f"{table}[{i}].{name} of {kind} {item.id!r}"
            series = _column(root, ref, tables, field=f"{table}[{i}].{name}", used_by=used_by)
            check_coverage(series, start, end, file=str(root / ref.file), field=ref.column, used_by=used_by)
            check_range(series, MAX_LEVEL if is_level else MAX_DISCHARGE, "m AD" if is_level else "m³/s",
                        file=str(root / ref.file), field=ref.column, used_by=used_by)
            if not is_level and (series < 0).any():
                bad = series.index[series < 0][0]
                raise CaseError(f"{ref.column}: a pump capacity cannot be negative, got {series[bad]:g} m³/s at "
                                f"{bad.isoformat()} (referenced by {used_by})", file=str(root / ref.file))
            key = f"{prefix}:{item.id}"
            series.name = key
            forcing[key] = series
    return forcing


def _column(root: Path, ref: SeriesRef, cache: dict[Path, SeriesTable], *, field: str, used_by: str) -> pd.Series:
    label = str(root / CASE_FILE)
    try:
        path = (root / ref.file).resolve()
        inside = path.is_relative_to(root.resolve())
    except (OSError, ValueError) as exc:
        raise CaseError(f"series file {ref.file!r} cannot be opened: {_one_line(exc)}", file=label,
                        field=f"{field}.file") from None
    if not inside:
        raise CaseError(f"series file {ref.file!r} lies outside the case folder", file=label, field=f"{field}.file")
    if not path.is_file():
        raise CaseError(f"series file {ref.file!r} not found in {root}", file=label, field=f"{field}.file")
    if path not in cache:
        cache[path] = read_series_table(path, label=str(root / ref.file), used_by=used_by)
    return series_column(cache[path], ref.column, used_by=used_by)
