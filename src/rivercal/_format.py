"""How numbers are shown to people: one rule per unit, level errors in cm, counted nouns.

The command line, the dashboard and the reports show a parameter value, its σ and a forecast error with
these functions, so that one quantity reads the same everywhere: a crest or a level to the centimetre
(``0.00 m``, never ``-1.476e-05`` or ``-0.0000``), a friction coefficient to a tenth, a level error in cm.
Machines get the stored number (JSON, CSV, the ``data-raw`` attributes of the dashboard), never these texts.
"""

from __future__ import annotations

import math

__all__ = ["decimals", "format_cm", "format_std", "format_value", "plural", "unit_suffix"]

#: Decimals shown per unit (the resolution that matters to the operator; thesis §4-2 uses cm and 0.5 m^(1/3)/s).
_DECIMALS = {"m": 2, "m AD": 2, "m NAP": 2, "m³/s": 2, "m3/s": 2, "m^(1/3)/s": 1, "m1/3/s": 1, "s/m^(1/3)": 3,
             "m^(1/2)/s": 1, "mm": 0, "cm": 1, "-": 2, "": 3}


def decimals(unit: str | None) -> int:
    """How many decimals a value in ``unit`` is shown with (3 for a unit without a rule)."""
    return _DECIMALS.get((unit or "").strip(), 3)


def _fixed(value: float, places: int) -> str:
    text = f"{value:.{places}f}"
    return text[1:] if text.startswith("-") and float(text) == 0.0 else text  # no "-0.00"


def unit_suffix(unit: str | None) -> str:
    """The unit as it follows a number in a sentence: `` m AD``; nothing for a dimensionless (``-``, ``1``) one."""
    text = (unit or "").strip()
    return "" if text in ("", "-", "1") else f" {text}"


def format_value(value: float | None, unit: str | None = None, *, with_unit: bool = False) -> str:
    """A parameter value or a level to the precision of its unit: ``0.00`` for -1.5e-05 m, ``24.3`` for k_s.

    Parameters
    ----------
    value
        The value in ``unit`` (None or NaN: an en dash).
    unit
        Its unit, e.g. ``m``, ``m AD``, ``m^(1/3)/s``, ``m³/s``, ``-``.
    with_unit
        Append the unit (not for ``-`` or an empty unit).
    """
    if value is None or not math.isfinite(float(value)):
        return "–"
    text = _fixed(float(value), decimals(unit))
    return f"{text} {unit}" if with_unit and unit and unit != "-" else text


def format_std(std: float | None, unit: str | None = None, *, with_unit: bool = False) -> str:
    """A standard deviation: the value's decimals, but never a σ of 0 that is not zero (``< 0.01``).

    Parameters
    ----------
    std
        σ in ``unit`` (None or NaN: an en dash).
    unit
        Its unit.
    with_unit
        Append the unit.
    """
    if std is None or not math.isfinite(float(std)):
        return "–"
    places = decimals(unit)
    text = _fixed(abs(float(std)), places)
    if float(text) == 0.0 and std != 0:
        text = f"< {10.0 ** -places:.{places}f}" if places else "< 1"
    return f"{text} {unit}" if with_unit and unit and unit != "-" else text


def format_cm(error_m: float | None, *, signed: bool = False) -> str:
    """A level error given in m, shown in cm with one decimal: ``3.4 cm`` (``+3.4 cm`` when ``signed``)."""
    if error_m is None or not math.isfinite(float(error_m)):
        return "–"
    cm = float(error_m) * 100.0
    text = _fixed(cm, 1)
    if signed and not text.startswith("-"):
        text = "+" + text
    return f"{text} cm"


def plural(n: int, noun: str, nouns: str | None = None) -> str:
    """A count with its noun in the right number: ``1 weir``, ``13 weirs``, ``2 boundaries``, ``2 branches``.

    ``nouns`` is the plural where the rules (``s``; ``es`` after s, x, z, ch, sh; ``y`` → ``ies``) are wrong,
    e.g. ``plural(n, "series", "series")``.
    """
    if n == 1:
        return f"{n} {noun}"
    if nouns is None:
        if noun.endswith("y") and noun[-2:-1] not in "aeiou":
            nouns = noun[:-1] + "ies"
        elif noun.endswith(("s", "x", "z", "ch", "sh")):
            nouns = noun + "es"
        else:
            nouns = noun + "s"
    return f"{n} {nouns}"
