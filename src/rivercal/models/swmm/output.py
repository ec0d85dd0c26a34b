"""Reading EPA SWMM's binary output file (``.out``) through swmm-toolkit's output API.

The file holds single-precision results at every reporting period; the first period is one reporting
step after the report start (SWMM 5 output file format). :func:`read_swmm_output` returns the series of
the requested nodes (hydraulic head, m) and links (flow rate, m³/s) indexed by UTC time.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["SWMM_EPOCH", "parse_element", "read_swmm_output"]

#: SWMM's dates are days since this moment (the spreadsheet epoch).
SWMM_EPOCH = pd.Timestamp("1899-12-30", tz="UTC")
#: The number that opens and closes a complete SWMM 5 binary output file.
MAGIC = 516114522


def _check_file(path: Path) -> None:
    """ValueError unless ``path`` is a complete SWMM output (magic numbers at both ends, error code 0).

    The toolkit's reader does not survive a truncated file (it crashes the process), so the file's
    opening and closing records (SWMM 5 user's manual, binary output file) are checked first.
    """
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = np.frombuffer(f.read(4), dtype="<i4")
        if size < 48:
            raise ValueError(f"{path}: not a SWMM output file or truncated ({size} bytes)")
        f.seek(size - 12)
        periods, error, magic = np.frombuffer(f.read(12), dtype="<i4")
    if head.size != 1 or head[0] != MAGIC:
        raise ValueError(f"{path}: not a SWMM output file (no SWMM magic number at its start)")
    if magic != MAGIC:
        raise ValueError(f"{path}: the SWMM output is truncated (no closing records; did SWMM stop early?)")
    if error != 0:
        raise ValueError(f"{path}: SWMM ended with error code {error}")
    if periods < 1:
        raise ValueError(f"{path}: the SWMM output holds no reporting period")


def parse_element(spec: str) -> tuple[str, str]:
    """``node:<id>`` (head, m) or ``link:<id>`` (flow, m³/s) → (kind, id); ValueError otherwise."""
    kind, sep, ident = spec.partition(":")
    if not sep or kind not in ("node", "link") or not ident:
        raise ValueError(f"{spec!r}: expected 'node:<id>' (head, m) or 'link:<id>' (flow, m³/s)")
    return kind, ident


def read_swmm_output(path: str | Path, elements: Mapping[str, str], *, step: float | None = None) -> pd.DataFrame:
    """Series of SWMM objects from a binary output file.

    Parameters
    ----------
    path
        The ``.out`` file.
    elements
        Column name → ``node:<id>`` (hydraulic head, m) or ``link:<id>`` (flow rate, m³/s).
    step
        The reporting step, s, when the caller knows it (the ``REPORT_STEP`` it wrote). The file holds it as
        whole seconds computed from fractional days, which SWMM may round down (3599 for one hour, with some
        start times); without ``step`` a value within 1 s of whole minutes is taken as those minutes.

    Returns
    -------
    DataFrame
        One column per element, indexed by the reporting times (UTC; SWMM's clock read as UTC).

    Raises
    ------
    ValueError
        When the file cannot be read (missing, truncated, not a SWMM output), has no reporting period,
        or does not hold a requested object; the message names the file.
    """
    from swmm.toolkit import output, shared_enum

    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such SWMM output file")
    wanted = {col: parse_element(spec) for col, spec in elements.items()}
    _check_file(path)
    handle = output.init()
    try:
        try:
            output.open(handle, str(path))
            n = output.get_times(handle, shared_enum.Time.NUM_PERIODS)
            stored = output.get_times(handle, shared_enum.Time.REPORT_STEP)
            start = output.get_start_date(handle)
            counts = output.get_proj_size(handle)
            index = {
                "node": {output.get_elem_name(handle, shared_enum.ElementType.NODE, i): i for i in range(counts[1])},
                "link": {output.get_elem_name(handle, shared_enum.ElementType.LINK, i): i for i in range(counts[2])},
            }
        except Exception as exc:  # the toolkit raises plain Exceptions with SWMM's error text
            raise ValueError(f"{path}: not a readable SWMM output file ({exc})") from None
        if n < 1:
            raise ValueError(f"{path}: the SWMM output holds no reporting period")
        columns = {}
        for col, (kind, ident) in wanted.items():
            if ident not in index[kind]:
                raise ValueError(f"{path}: the SWMM output has no {kind} {ident!r} (is it in the [REPORT] section?)")
            if kind == "node":
                values = output.get_node_series(handle, index[kind][ident],
                                                shared_enum.NodeAttribute.HYDRAULIC_HEAD, 0, n - 1)
            else:
                values = output.get_link_series(handle, index[kind][ident], shared_enum.LinkAttribute.FLOW_RATE,
                                                0, n - 1)
            columns[col] = np.asarray(values, dtype=float)
    finally:
        output.close(handle)
    if step is None:
        minutes = round(stored / 60.0) * 60.0
        step = minutes if minutes > 0 and abs(stored - minutes) <= 1.0 else float(stored)
    first = SWMM_EPOCH + pd.Timedelta(days=start) + pd.Timedelta(seconds=step)
    times = (first + pd.to_timedelta(np.arange(n) * step, unit="s")).round("s")
    frame = pd.DataFrame(columns, index=pd.DatetimeIndex(times, name="time"))
    return frame
