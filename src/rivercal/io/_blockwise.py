"""Block-wise time series of D-HYDRO and SOBEK 3 ``.bc`` files as the linear series a case holds.

hydrolib-core's ``TimeInterpolation`` (and DeltaShell's, which SOBEK 3 writes): ``block-From`` holds each value
from its time to the next time ("equal to that at the start of the time interval"); ``block-To`` gives each
interval the value at its end ("equal to that at the end of the time interval (upcoming specified time value)"),
so the first value holds at the first time only. A case interpolates its series linearly, so each change takes
``STEP_SECONDS`` (or half the interval, where that is shorter).
"""

from __future__ import annotations

import pandas as pd

__all__ = ["STEP_SECONDS", "block_steps"]

#: Duration of a change of value of a block-wise series in the case's (linear) series, s.
STEP_SECONDS = 1.0


def block_steps(series: pd.Series, how: str) -> pd.Series:
    """A block-wise series as the change points of a linear one.

    ``series`` holds values at increasing times, held as ``how`` says (``"block-from"`` or ``"block-to"``); a time
    given twice keeps its later row.
    """
    t, v = list(series.index), [float(x) for x in series.to_numpy(dtype=float)]
    out_t, out_v = [t[0]], [v[0]]
    for k in range(1, len(t)):
        if t[k] <= t[k - 1]:
            out_t.append(t[k])
            out_v.append(v[k])
            continue
        ramp = min(pd.Timedelta(seconds=STEP_SECONDS), (t[k] - t[k - 1]) / 2)
        if how == "block-from":  # v[k-1] up to t[k], then v[k]
            out_t += [t[k] - ramp, t[k]]
            out_v += [v[k - 1], v[k]]
        else:  # v[k] from just after t[k-1] up to t[k]
            out_t += [t[k - 1] + ramp, t[k]]
            out_v += [v[k], v[k]]
    out = pd.Series(out_v, index=pd.DatetimeIndex(out_t))
    return out[~out.index.duplicated(keep="last")]
