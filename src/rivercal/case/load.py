"""Loading a case: a folder with ``case.toml`` and the CSV series it references.

``load_case`` accepts a folder or the name of a case shipped in the package
(``rivercal/cases/<name>/``). Every problem is raised at load time as a
:class:`~rivercal.errors.CaseError` that names the file, the field and what is wrong, so that the
engine never sees an invalid case.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import pandas as pd
from pydantic import ValidationError

from rivercal.case.schema import CaseFile
from rivercal.case.series import check_coverage, read_series_csv
from rivercal.errors import CaseError
from rivercal.network.schema import Network, SeriesRef

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
        stored as two-point series spanning the period.
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
        return pd.Timestamp(self.spec.case.start)

    @property
    def end(self) -> pd.Timestamp:
        """End of the simulated period (UTC)."""
        return pd.Timestamp(self.spec.case.end)

    @property
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
    try:
        data = tomllib.loads(toml_path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"not valid TOML: {exc}", file=CASE_FILE) from exc
    except UnicodeDecodeError as exc:
        raise CaseError(f"not UTF-8 text: {exc}", file=CASE_FILE) from exc
    return case_from_dict(data, root)


def case_from_dict(data: dict[str, Any], root: Path) -> Case:
    """Validate a parsed ``case.toml`` and load the series it references from ``root``.

    Raises
    ------
    CaseError
        Naming the file, the field and the problem.
    """
    try:
        spec = CaseFile.model_validate(data)
    except ValidationError as exc:
        raise _case_error(exc) from None
    except (ValueError, TypeError, OverflowError) as exc:  # raised by a validator outside pydantic's wrapping
        raise CaseError(str(exc), file=CASE_FILE) from None
    forcing = _load_forcing(spec, root)
    return Case(spec=spec, root=root, forcing=forcing)


def _case_error(exc: ValidationError) -> CaseError:
    err = exc.errors(include_url=False)[0]
    loc = _format_loc(err.get("loc", ()))
    msg = str(err.get("msg", "invalid value"))
    msg = msg.removeprefix("Value error, ")
    if err.get("type") == "missing":
        msg = "required field is missing"
    elif err.get("type") == "extra_forbidden":
        msg = "unknown field (check the spelling; see `rivercal case schema`)"
    more = exc.error_count() - 1
    if more:
        msg += f" (and {more} more problem{'s' if more > 1 else ''})"
    return CaseError(msg, file=CASE_FILE, field=loc or None)


def _format_loc(loc: tuple) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        elif part in ("rectangular", "trapezoidal", "zw", "function-after[_not_degenerate(), TrapezoidalProfile]"):
            continue
        elif str(part).startswith(("function-", "tagged-union[")):
            continue
        else:
            out += f".{part}" if out else str(part)
    return out


def _load_forcing(spec: CaseFile, root: Path) -> dict[str, pd.Series]:
    start, end = pd.Timestamp(spec.case.start), pd.Timestamp(spec.case.end)
    files: dict[str, pd.DataFrame] = {}
    forcing: dict[str, pd.Series] = {}
    items = [("boundaries", "boundary", b) for b in spec.boundaries] + [
        ("laterals", "lateral", lat) for lat in spec.laterals
    ]
    counters: dict[str, int] = {}
    for table, kind, item in items:
        i = counters[table] = counters.get(table, -1) + 1
        key = f"{kind}:{item.id}"
        if getattr(item, "type", None) == "rating":
            continue
        if item.value is not None:
            forcing[key] = pd.Series([item.value, item.value], index=pd.DatetimeIndex([start, end]), name=key)
            continue
        ref: SeriesRef = item.series
        forcing[key] = _column(root, ref, files, field=f"{table}[{i}].series")
        check_coverage(forcing[key], start, end, file=ref.file, field=ref.column)
        forcing[key].name = key
    return forcing


def _column(root: Path, ref: SeriesRef, cache: dict[str, pd.DataFrame], *, field: str) -> pd.Series:
    path = (root / ref.file).resolve()
    if not path.is_relative_to(root.resolve()):
        raise CaseError(f"series file {ref.file!r} lies outside the case folder", file=CASE_FILE, field=field)
    if not path.is_file():
        raise CaseError(f"series file {ref.file!r} not found in {root}", file=CASE_FILE, field=field)
    if ref.file not in cache:
        cache[ref.file] = read_series_csv(path, label=ref.file)
    frame = cache[ref.file]
    if ref.column not in frame.columns:
        raise CaseError(
            f"column {ref.column!r} not in {ref.file} (columns: {', '.join(frame.columns)})",
            file=CASE_FILE,
            field=field,
        )
    return frame[ref.column].copy()
