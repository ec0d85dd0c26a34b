"""The command line's own checks of option values: everything is parsed and checked before the first run.

Every function here raises :class:`~rivercal.errors.OptionError` with a message that names the option
and the value (the command then exits with status 2). Only pure validation of the user's values is
done here; running a model is the workflows' job (:mod:`rivercal.workflows`).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from rivercal.errors import OptionError

__all__ = [
    "WINDOW_HELP",
    "check_choice",
    "check_number",
    "check_truth",
    "check_workers",
    "dask_address",
    "input_file",
    "open_model",
    "optimiser_options",
    "output_dir",
    "output_file",
    "parse_assignments",
    "parse_duration",
    "parse_names",
    "parse_sets",
    "parse_time",
    "parse_window",
    "read_observations",
    "select_parameters",
    "window_observations",
    "workers_for",
]


def open_model(argument: str, *, show_compilation: bool = True) -> Any:
    """The model a CASE argument names.

    A case folder, its ``case.toml``, the name of a packaged case, or a ``model.toml`` of another model
    (or a folder holding one; :func:`rivercal.models.load_model`). Every command takes its CASE through
    here. A bad case or model file raises :class:`~rivercal.errors.CaseError` (file, field, problem).
    """
    from rivercal.cli.common import watch_compilation
    from rivercal.model import load_model

    watch_compilation(show_compilation)
    return load_model(argument)


# -- where the runs go -----------------------------------------------------------------------------


def dask_address(address: str | None, workers: int | None) -> str | None:
    """Check ``--dask`` (``local:N`` or ``tcp://HOST:PORT``) and that it is not given with ``--workers``."""
    import re

    if address is None:
        return None
    if workers is not None:
        raise OptionError("give either --workers (local processes) or --dask (a Dask cluster), not both",
                          option="--dask")
    text = address.strip()
    local = re.fullmatch(r"local:(\d+)", text)
    if local is not None and int(local.group(1)) >= 1:
        check_workers(int(local.group(1)), f"--dask {address}: N =")
        return text
    if local is None and re.fullmatch(r"(tcp|tls)://[^\s/:]+:\d+/?", text):
        return text
    raise OptionError(f"--dask {address!r}: expected local:N (N ≥ 1 worker processes on this machine) or "
                      "tcp://HOST:PORT (the address of a running Dask scheduler)", option="--dask")


def check_workers(workers: int | None, option: str = "--workers") -> None:
    """``--workers``: a whole number from 1 to the cores available to this process (None: all of them).

    More is refused with the limit, not cut down (:func:`rivercal.evaluate.check_workers` says why).
    """
    from rivercal.evaluate import check_workers as check

    try:
        check(workers, option)
    except ValueError as exc:
        raise OptionError(str(exc), option=option.split()[0]) from None


@contextlib.contextmanager
def workers_for(workers: int | None, address: str | None) -> Iterator[Any]:
    """The workers of a command: ``--workers`` as given, or a Dask cluster for ``--dask`` (closed after)."""
    if address is None:
        yield workers
        return
    from rivercal.evaluate import DaskCluster

    with DaskCluster(address) as cluster:
        yield cluster


# -- numbers, names and choices -------------------------------------------------------------------


def check_number(value: float | None, option: str, *, low: float | None = None, high: float | None = None,
                 low_open: bool = False, high_open: bool = False) -> None:
    """A finite number inside [low, high] (an open end with ``low_open``/``high_open``); None passes."""
    if value is None:
        return
    if not math.isfinite(value):
        raise OptionError(f"{option} {value}: must be a finite number", option=option)
    too_low = low is not None and (value <= low if low_open else value < low)
    too_high = high is not None and (value >= high if high_open else value > high)
    if too_low or too_high:
        lo = "" if low is None else f"{'(' if low_open else '['}{low:g}"
        hi = "" if high is None else f"{high:g}{')' if high_open else ']'}"
        where = f"in {lo}, {hi}" if low is not None and high is not None else (
            f"{'above' if low_open else 'at least'} {low:g}" if low is not None else
            f"{'below' if high_open else 'at most'} {high:g}")
        raise OptionError(f"{option} {value:g}: must be {where}", option=option)


def check_choice(value: str, option: str, choices: Iterable[str], what: str = "choice",
                 former: Mapping[str, str] | None = None) -> str:
    """``value`` if it is one of ``choices`` (``what`` names them in the message, e.g. 'practical scenario').

    ``former`` maps names that were renamed to what they are called now; asking for one says so.
    """
    choices = list(choices)
    if former and value in former:
        raise OptionError(f"{option} {value!r}: it is now called {former[value]}", option=option)
    if value not in choices:
        raise OptionError(f"{option} {value!r}: unknown {what}; choose one of {', '.join(choices)}", option=option)
    return value


def parse_names(text: str | None, option: str) -> list[str]:
    """'FA, Wc' → ['FA', 'Wc'] (comma-separated, blanks dropped, no duplicates)."""
    names = [n.strip() for n in (text or "").split(",") if n.strip()]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise OptionError(f"{option} {text!r}: {twice[0]!r} is named twice", option=option)
    return names


def parse_assignments(text: str | None, option: str, example: str = "FA=20") -> dict[str, float]:
    """'FA=20,Wc=0.8' → {'FA': 20.0, 'Wc': 0.8}: finite numbers, each name once."""
    out: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in (text or "").split(","))):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise OptionError(f"{option} {item!r}: expected NAME=VALUE, e.g. {option} {example}", option=option)
        try:
            number = float(value)
        except ValueError:
            raise OptionError(f"{option} {item!r}: {value.strip()!r} is not a number", option=option) from None
        if not math.isfinite(number):
            raise OptionError(f"{option} {item!r}: the value must be a finite number", option=option)
        if name in out:
            raise OptionError(f"{option} {item!r}: {name!r} is given twice", option=option)
        out[name] = number
    return out


def parse_sets(values: list[str], model: Any | None = None) -> dict[str, float]:
    """Repeated ``--set TARGET=VALUE`` → {target: value}; checked against the model when it is given."""
    out: dict[str, float] = {}
    for item in values:
        for name, value in parse_assignments(item, "--set", example="friction:global=20").items():
            if name in out:
                raise OptionError(f"--set {name}: given twice", option="--set")
            out[name] = value
    if model is not None and out:
        from rivercal.models.contract import check_settable

        for name, value in out.items():
            try:  # the model's own check of a target and its value; pure, it runs nothing
                if hasattr(model, "parameter_arrays"):  # the embedded engine words its checks for a case
                    model.parameter_arrays({name: value})
                else:
                    check_settable(model, [name])
                    model.quantities[name].check(value)
            except (KeyError, ValueError) as exc:
                text = str(exc.args[0] if isinstance(exc, KeyError) and exc.args else exc).removeprefix(f"{name}: ")
                raise OptionError(f"--set {name}={value:g}: {text}", option="--set") from None
            _check_with_case(model, name, value)
    return out


def _check_with_case(model: Any, name: str, value: float) -> None:
    """``--set`` under the case's own rules: the case with the value in place must still load.

    A crest set below the bed is refused as ``case.toml`` refuses it (the case's validation runs on a copy
    of the case with the crest in place; nothing is written). Models without a case have only the bounds
    of their quantities.
    """
    case = getattr(model, "case", None)
    spec = getattr(case, "spec", None)
    if spec is None or not (name.startswith("weir:") and name.endswith(".crest_level")):
        return
    from rivercal.case.load import case_from_dict
    from rivercal.errors import CaseError
    from rivercal.network import STRUCTURE_TABLES

    ident = name.removeprefix("weir:").removesuffix(".crest_level")
    data = spec.model_dump(by_alias=True, exclude_unset=True)
    placed = False
    for table, _ in STRUCTURE_TABLES:
        for item in data.get(table) or []:
            if item.get("id") == ident and "crest_level" in item:
                item["crest_level"] = float(value)
                placed = True
    if not placed:
        return
    try:
        case_from_dict(data, case.root)
    except CaseError as exc:
        where = f" at {exc.field}" if exc.field else ""
        raise OptionError(f"--set {name}={value:g}: {exc.reason}; case.toml refuses the same value{where}",
                          option="--set") from None


# -- times -----------------------------------------------------------------------------------------


def parse_time(text: str, option: str) -> Any:
    """An ISO 8601 time as a UTC timestamp (a time without zone is UTC); other forms are refused, never guessed.

    ``10-11-2010`` is 10 November to a Dutch reader and October 11 to pandas: such a date is refused with
    both readings (:func:`rivercal._time.parse_iso`).
    """
    from rivercal._time import utc

    try:
        return utc(text)
    except (ValueError, TypeError, OverflowError) as exc:
        raise OptionError(f"{option} {exc}", option=option) from None


def parse_duration(text: str, option: str, *, allow_zero: bool = False) -> Any:
    """A positive duration such as '7D', '48h' or '90min' (zero too with ``allow_zero``)."""
    import pandas as pd

    try:
        value = pd.Timedelta(text)
    except (ValueError, TypeError, OverflowError):
        value = None
    if value is None or value is pd.NaT:
        raise OptionError(f"{option} {text!r}: not a duration (e.g. 7D, 48h, 90min)", option=option)
    if value < pd.Timedelta(0) or (value == pd.Timedelta(0) and not allow_zero):
        raise OptionError(f"{option} {text!r}: must be {'zero or ' if allow_zero else ''}positive", option=option)
    return value


#: What ``--window`` of calibrate, analyse, twin and advise takes, for the help and the messages.
WINDOW_HELP = ("The calibration window: a date range START/END in UTC (ISO 8601, e.g. 2010-09-27/2010-10-04, or "
               "START/DURATION, e.g. 2010-09-27/7D) or the name of a window of the case (e.g. moderate). Not a "
               "length alone: that is what 'rivercal online --window' takes (each cycle's window, e.g. 7D).")


def parse_window(model: Any, text: str, *, option: str = "--window", warmup: Any = None,
                 warmup_option: str | None = "--warmup") -> tuple[Any, Any]:
    """A window of the model (case) by name, or ``START/END`` or ``START/DURATION``, as UTC timestamps in its period.

    A name matches regardless of case when only one window has it. A duration alone (``7D``) is refused
    with what it would mean elsewhere: ``rivercal online --window`` is a length, here a window is a range.
    With ``warmup`` (a Timedelta) the runs start that long before the window; that start must lie in
    the period too (``warmup_option`` names the option that sets it, None when none does).
    """
    import pandas as pd

    named = dict(model.calibration.windows)
    folded = [n for n in named if n.lower() == text.strip().lower()]
    known = ", ".join(named) or "none"
    if text in named or len(folded) == 1:
        a, b = (parse_time(str(t), option) for t in named[text if text in named else folded[0]])
    else:
        first, sep, second = text.partition("/")
        if not sep:
            if _duration(text) is not None:
                raise OptionError(f"{option} {text!r}: a length, not a window; give a date range START/END (e.g. "
                                  f"2010-09-27/2010-10-04), START/DURATION (e.g. 2010-09-27/{text.strip()}) or a "
                                  f"window of the case ({known}). ('rivercal online --window' is the length of each "
                                  "cycle's window.)", option=option)
            period = f"{model.start:%Y-%m-%d %H:%M} .. {model.end:%Y-%m-%d %H:%M}"
            if not named:  # e.g. analyse's default 'moderate' on an imported model, which names no windows
                raise OptionError(f"{option} {text!r}: not a window of {model.name!r}, which names none (an imported "
                                  f"model has none); give a date range START/END or START/DURATION in its period "
                                  f"{period}, e.g. {model.start:%Y-%m-%d}/1D", option=option)
            raise OptionError(f"{option} {text!r}: expected START/END (e.g. 2010-09-27/2010-10-04) or a window of "
                              f"the case ({known}); its period is {period}", option=option)
        a = parse_time(first, option)
        length = _duration(second)
        if length is not None:
            if length <= pd.Timedelta(0):
                raise OptionError(f"{option} {text!r}: the duration after the start must be positive", option=option)
            b = a + length
        else:
            b = parse_time(second, option)
    if not b > a:
        raise OptionError(f"{option} {text!r}: the end is not after the start", option=option)
    if a < model.start or b > model.end:
        raise OptionError(f"{option} {text!r}: lies outside the case period {model.start:%Y-%m-%d %H:%M} .. "
                          f"{model.end:%Y-%m-%d %H:%M}", option=option)
    _check_on_output_times(model, a, b, option, text, warmup, warmup_option)
    if warmup is not None and a - warmup < model.start:
        hours = pd.Timedelta(warmup).total_seconds() / 3600
        which = f" ({warmup_option})" if warmup_option else ""
        raise OptionError(f"{option} {text!r}: the runs start {hours:g} h{which} before the window, "
                          f"at {a - warmup:%Y-%m-%d %H:%M}, before the case starts ({model.start:%Y-%m-%d %H:%M}); "
                          f"start the window at {model.start + warmup:%Y-%m-%d %H:%M} or later"
                          + (f", or shorten {warmup_option}" if warmup_option else ""), option=option)
    return a, b


def _duration(text: str) -> Any:
    """``text`` as a duration when it is written as one (``7D``, ``48h``, ``P7D``), else None (a date is not)."""
    import re

    import pandas as pd

    stripped = text.strip()
    if not re.fullmatch(r"(P[0-9WDTHMS.]+|[0-9.]+\s*[A-Za-z]+(\s*[0-9.]+\s*[A-Za-z]+)*)", stripped):
        return None
    try:
        value = pd.Timedelta(stripped)
    except (ValueError, TypeError, OverflowError):
        return None
    return None if value is pd.NaT else value


def _check_on_output_times(model: Any, a: Any, b: Any, option: str, text: str, warmup: Any,
                           warmup_option: str | None) -> None:
    """A window (and its warm-up) on the model's output times: every run is a whole number of output intervals."""
    import pandas as pd

    from rivercal.online.config import span

    step = pd.Timedelta(seconds=float(getattr(model, "output_interval", 0) or 0))
    if step <= pd.Timedelta(0):
        return
    start = pd.Timestamp(model.start)
    off = [t for t in (a, b) if (t - start) % step]
    if off:
        t = off[0]
        before = start + ((t - start) // step) * step
        raise OptionError(f"{option} {text!r}: {t:%Y-%m-%d %H:%M:%S} is not one of the model's output times (every "
                          f"{span(step)} from {start:%Y-%m-%d %H:%M}); e.g. {before:%Y-%m-%d %H:%M} or "
                          f"{before + step:%Y-%m-%d %H:%M}", option=option)
    if warmup is not None and pd.Timedelta(warmup) % step:
        which = warmup_option or "the warm-up"
        hours = pd.Timedelta(warmup).total_seconds() / 3600
        raise OptionError(f"{which} {hours:g}: the warm-up must be a whole number of the model's output interval "
                          f"({span(step)})", option=warmup_option or option)


# -- parameters ------------------------------------------------------------------------------------


def select_parameters(model: Any, names: str, start: Mapping[str, float], bounds: list[str]) -> Any:
    """The model's parameters named in ``names`` (``--params``), with ``--start`` and ``--bounds`` applied."""
    from rivercal.parameters import ParameterSet

    wanted = parse_names(names, "--params")
    if not wanted:
        raise OptionError("--params: give at least one parameter name", option="--params")
    known = {p.name: p for p in model.calibration.parameters}
    for n in wanted:
        if n not in known:
            raise OptionError(f"--params: unknown parameter {n!r}; {_defines(model)} {', '.join(known) or 'none'}",
                              option="--params")
    updates: dict[str, dict[str, float]] = {n: {} for n in wanted}
    for item in bounds:
        name, sep, rng = item.partition("=")
        low, colon, high = rng.partition(":")
        if not sep or not colon or name.strip() not in updates:
            raise OptionError(f"--bounds {item!r}: expected NAME=MIN:MAX for a parameter in --params",
                              option="--bounds")
        try:
            lo, hi = float(low), float(high)
        except ValueError:
            raise OptionError(f"--bounds {item!r}: MIN and MAX must be numbers", option="--bounds") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise OptionError(f"--bounds {item!r}: MIN and MAX must be finite with MIN below MAX", option="--bounds")
        updates[name.strip()].update(min=lo, max=hi)
    for name, value in start.items():
        if name not in updates:
            raise OptionError(f"--start {name}={value:g}: {name!r} is not in --params", option="--start")
        updates[name]["initial"] = value
    from rivercal.models.contract import check_parameters

    chosen = []
    for n in wanted:
        p = known[n]
        merged = {**p.model_dump(), **updates[n]}
        lo, hi, x0 = merged["min"], merged["max"], merged["initial"]
        if not lo <= x0 <= hi:
            option = "--start" if "initial" in updates[n] else "--bounds"
            raise OptionError(f"{option}: the start value {x0:g} of {n} lies outside its bounds [{lo:g}, {hi:g}]"
                              + (" (the case's start value; give --start too)" if option == "--bounds" else ""),
                              option=option)
        option = "--bounds" if "min" in updates[n] else "--start"
        try:
            chosen.append(type(p).model_validate(merged))
        except ValueError as exc:  # the parameter's own rules, e.g. a cluster lives in [0, 1]
            raise OptionError(f"{option}: parameter {n}: {_first_problem(exc)}", option=option) from None
        try:  # and the model's: the quantities it sets stay inside the bounds the model declares
            check_parameters(model, [chosen[-1]])
        except ValueError as exc:
            given = next((b for b in bounds if b.partition("=")[0].strip() == n), None) if option == "--bounds" \
                else None
            raise OptionError(f"{option}{' ' + given if given else ''}: {exc}", option=option) from None
    check_overlap(model, wanted)
    return ParameterSet(chosen)


def check_overlap(model: Any, names: Iterable[str]) -> None:
    """The parameters ``names`` of ``--params`` (all defined by the model) set different model quantities.

    Refused, for instance: a weir's crest level and the shift of all crests, which both set that weir's crest.
    """
    from rivercal.parameters import shared_quantity

    shared = shared_quantity(model.calibration.parameter(n) for n in names)
    if shared is not None:
        first, second, quantity = shared
        raise OptionError(f"--params: {first} and {second} both set {quantity}; give only one of them",
                          option="--params")


def check_truth(parameters: Any, truth: Mapping[str, float], option: str = "--twin") -> None:
    """True values of a twin experiment: each names a parameter of ``--params`` and lies in its bounds."""
    for name, value in truth.items():
        if name not in parameters.names:
            raise OptionError(f"{option} {name}={value:g}: {name!r} is not in --params", option=option)
        p = parameters[name]
        if not p.min <= value <= p.max:
            raise OptionError(f"{option} {name}={value:g}: outside the bounds [{p.min:g}, {p.max:g}] of {name}",
                              option=option)


def _what(model: Any) -> str:
    """'case dommel' or 'model dommel-swmm' for messages."""
    return f"{'case' if hasattr(model, 'case') else 'model'} {model.name!r}"


def _defines(model: Any) -> str:
    return f"{'the case' if hasattr(model, 'case') else 'model ' + repr(model.name)} defines"


def _first_problem(exc: ValueError) -> str:
    errors = getattr(exc, "errors", None)
    if callable(errors):
        first = errors()[0]
        return str(first.get("ctx", {}).get("error") or first.get("msg"))
    return str(exc)


# -- files and folders -----------------------------------------------------------------------------


def input_file(path: Path, option: str, suffixes: Iterable[str] | None = None) -> Path:
    """An existing, readable file (with one of ``suffixes`` when given)."""
    if not path.is_file():
        what = "is a folder, not a file" if path.is_dir() else "no such file"
        raise OptionError(f"{option} {path}: {what}", option=option)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        raise OptionError(f"{option} {path}: expected a file ending in {' or '.join(suffixes)}", option=option)
    return path


def read_observations(path: Path, option: str = "--observations") -> Any:
    """The observations of a CSV, PI-XML or sidecar TOML file; a bad file names the option, the file and the line."""
    from rivercal.errors import CaseError
    from rivercal.io.observations import read_observations as read_any
    from rivercal.workflows.online import read_observation_file

    input_file(path, option, (".csv", ".xml", ".toml"))
    try:
        return read_any(path) if path.suffix.lower() == ".toml" else read_observation_file(path)
    except CaseError as exc:
        raise OptionError(f"{option} {exc}", option=option) from None


def window_observations(path: Path, model: Any, window: tuple[Any, Any], option: str = "--observations") -> Any:
    """The observations of a file inside ``window``: at least one value, every series simulated by ``model``."""
    obs = read_observations(path, option).within(*window)
    if obs.n_values == 0:
        raise OptionError(f"{option} {path}: no observations in the window {window[0]:%Y-%m-%d %H:%M} .. "
                          f"{window[1]:%Y-%m-%d %H:%M}", option=option)
    unknown = [s for s in obs.ids if s not in model.observables]
    if unknown:
        raise OptionError(f"{option} {path}: series {unknown[0]!r} is not simulated by {_what(model)} (it "
                          f"simulates {', '.join(model.observables)})", option=option)
    return obs


def output_dir(path: Path, option: str = "--out") -> Path:
    """A folder to write into: created if missing; an error when it cannot be, or cannot be written to."""
    if path.exists() and not path.is_dir():
        raise OptionError(f"{option} {path}: exists and is not a folder", option=option)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OptionError(f"{option} {path}: cannot create the folder ({exc.strerror or exc})", option=option) from None
    _writable(path, path, option)
    return path


def output_file(path: Path, option: str) -> Path:
    """A file to write: its folder is created; an existing folder of that name is an error."""
    if path.is_dir():
        raise OptionError(f"{option} {path}: is a folder; give a file name", option=option)
    if path.parent.exists() and not path.parent.is_dir():
        raise OptionError(f"{option} {path}: {path.parent} is not a folder", option=option)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OptionError(f"{option} {path}: cannot create its folder {path.parent} ({exc.strerror or exc})",
                          option=option) from None
    _writable(path.parent, path, option)
    return path


def _writable(folder: Path, given: Path, option: str) -> None:
    """Create and remove a file in ``folder``: a folder that cannot take files (read-only, /proc) fails here."""
    import tempfile

    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".rivercal-", suffix=".probe"):
            pass
    except OSError as exc:
        raise OptionError(f"{option} {given}: cannot write into {folder} ({exc.strerror or exc})",
                          option=option) from None


# -- optimiser options -----------------------------------------------------------------------------


def optimiser_options(algorithm: str, items: list[str], defaults: Mapping[str, Any], parameters: Any) -> dict:
    """``--option KEY=VALUE`` (repeatable) over ``defaults``, typed by the algorithm's options dataclass.

    The optimiser's own checks then run on a stand-in problem of the same size (the residuals x − x0,
    one evaluation, no model), so that a bad value fails here, before any model run.
    """
    import dataclasses
    import typing

    import numpy as np

    from rivercal.optimise import OPTIMISERS

    cls = _options_class(algorithm)
    hints = typing.get_type_hints(cls)
    fields = {f.name: hints[f.name] for f in dataclasses.fields(cls)}
    opts = dict(defaults)
    for item in items:
        key, sep, text = (part.strip() for part in item.partition("="))
        if not sep or not key:
            raise OptionError(f"--option {item!r}: expected KEY=VALUE, e.g. --option max_outer=10", option="--option")
        if key not in fields:
            raise OptionError(f"--option {item!r}: {algorithm} has no option {key!r}; it has "
                              f"{', '.join(fields)}", option="--option")
        opts[key] = _typed(item, text, fields[key])
    x0 = np.asarray(parameters.to_x(), dtype=float)
    lb, ub = parameters.bounds()
    try:
        OPTIMISERS[algorithm](lambda x: np.asarray(x, dtype=float) - x0, x0, lb, ub, options=opts, max_nfev=1)
    except (ValueError, TypeError) as exc:
        source = "--option" if items else "the case's [calibration] options"
        raise OptionError(f"{source}: {algorithm} refuses its options: {exc}", option="--option") from None
    return opts


def _options_class(algorithm: str) -> type:
    from rivercal.optimise import OPTIONS

    return OPTIONS[algorithm]


def _typed(item: str, text: str, kind: Any) -> Any:
    """The value of ``--option KEY=TEXT`` as the field's type (int, float, bool or str)."""
    import typing

    args = [a for a in typing.get_args(kind) if a is not type(None)]
    base = args[0] if len(args) == 1 else kind
    if text.lower() == "none" and type(None) in typing.get_args(kind):
        return None
    if base is bool:
        if text.lower() in ("true", "yes", "1", "on"):
            return True
        if text.lower() in ("false", "no", "0", "off"):
            return False
        raise OptionError(f"--option {item!r}: expected true or false", option="--option")
    if base in (int, float):
        try:
            value = float(text)
        except ValueError:
            raise OptionError(f"--option {item!r}: {text!r} is not a number", option="--option") from None
        if not math.isfinite(value):
            raise OptionError(f"--option {item!r}: the value must be a finite number", option="--option")
        if base is int:
            if value != int(value):
                raise OptionError(f"--option {item!r}: expected a whole number", option="--option")
            return int(value)
        return value
    if base is str:
        return text
    raise OptionError(f"--option {item!r}: this option takes an array or a function and cannot be set on the "
                      "command line", option="--option")


def read_dependency(path: Path | None, threshold: float, algorithm: str, names: Sequence[str]) -> Any:
    """``--dependency FILE``, a map as ``rivercal analyse`` writes it, checked against the run (None without)."""
    check_number(threshold, "--dependency-threshold", low=0)
    if path is None:
        return None
    from rivercal.analysis.dependency import DependencyMap

    if algorithm != "sparse_dud":
        raise OptionError(f"--dependency: a dependency map serves --algorithm sparse_dud only, not {algorithm}",
                          option="--dependency")
    try:
        dependency = DependencyMap.from_csv(path, threshold)
    except ValueError as exc:
        raise OptionError(f"--dependency: {exc}", option="--dependency") from None
    named = list(dependency.effects.columns)
    if not set(named) & set(names):
        raise OptionError(f"--dependency {path}: the map names none of --params ({', '.join(names)}); it names "
                          f"{', '.join(named)}", option="--dependency")
    return dependency
