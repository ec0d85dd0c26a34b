"""The identifiability verdict in plain language: one sentence per parameter and per suggested group.

:mod:`rivercal.analysis.identifiability` computes the numbers and the verdicts; this module turns an
:class:`~rivercal.analysis.identifiability.Identifiability` into sentences a water manager can act on:
which station sees a parameter, how precisely the observations determine it, which parameters the
observations cannot tell apart (and what change of them they hardly notice), and whether to cluster or
fix them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from rivercal.analysis.identifiability import (
    IDENTIFIABLE,
    NOT_IDENTIFIABLE,
    ClusterSuggestion,
    Identifiability,
    station_shares,
)

__all__ = ["explanations", "suggestion", "suggestions", "summary", "text", "verdict_table"]

_WHY = {"indistinct": "they cannot be told apart", "unseen": "none of them is seen on its own"}


def explanations(ident: Identifiability) -> dict[str, str]:
    """One sentence (or a few) per parameter, by name."""
    words = _Words(ident)
    return {name: words.parameter(i) for i, name in enumerate(ident.names)}


def suggestion(ident: Identifiability, cluster: ClusterSuggestion) -> str:
    """What to do with one suggested group, in words."""
    listed = _and(cluster.members)
    strength = _pct(cluster.strength)
    if ident.extra.get("unseen"):  # nothing is seen: the share of the best-seen combination says nothing
        one = len(cluster.members) == 1
        return (f"fix {listed} at {'its current value' if one else 'their current values'}: moved over "
                f"{ident.scale_name} {'it changes' if one else 'they change'} the misfit by less than one "
                "observation error.")
    if len(cluster.members) == 1:
        return (f"fix {listed} at its current value: the stations hardly see it (seen {strength} as strongly as the "
                "best-seen combination).")
    why = _WHY[cluster.reason]
    if cluster.action == "cluster":
        return (f"cluster {listed} into one parameter ({why}; as the thesis' Wc does, every member at the same "
                f"fraction of its range): moved together they are seen {strength} as strongly as the best-seen "
                "combination, enough to estimate the cluster.")
    return (f"fix {listed} at their current values ({why}): even moved together, every one at the same fraction of "
            f"its range, they are seen only {strength} as strongly as the best-seen combination.")


def suggestions(ident: Identifiability) -> list[str]:
    """One sentence per suggested group, in the order of ``ident.clusters``."""
    return [suggestion(ident, c) for c in ident.clusters]


def verdict_table(ident: Identifiability) -> pd.DataFrame:
    """The verdict table with an ``explanation`` column."""
    frame = ident.verdict.copy()
    words = explanations(ident)
    frame["explanation"] = [words[n] for n in ident.names]
    return frame


def summary(ident: Identifiability) -> dict[str, Any]:
    """``ident.summary()`` with the sentences: ``explanations`` by parameter, an ``explanation`` per cluster."""
    out = ident.summary()
    out["explanations"] = explanations(ident)
    out["clusters"] = [{**c.to_dict(), "explanation": suggestion(ident, c)} for c in ident.clusters]
    return out


def text(ident: Identifiability) -> str:
    """The verdict in words, one paragraph per parameter and per suggested cluster."""
    lines = list(explanations(ident).values())
    lines += [f"Suggestion: {s}" for s in suggestions(ident)]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------------
# sentences
# --------------------------------------------------------------------------------------------------


def _and(items: Sequence[str]) -> str:
    """``A``, ``A and B``, ``A, B and C``."""
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def _pct(fraction: float) -> str:
    """A share as a percentage with the digits that matter (25%, 2.4%, 0.009%)."""
    if fraction < 1e-6:
        return "practically 0%"
    if fraction >= 0.1:
        return f"{fraction:.0%}"
    if fraction >= 0.001:
        return f"{fraction:.1%}"
    return f"{100 * fraction:.1g}%"


def _level(value: float) -> str:
    """A level difference (m) in cm below 1 m."""
    return f"{100 * value:.2g} cm" if value < 1 else f"{value:.3g} m"


class _Words:
    """Plain-language sentences for one analysis."""

    def __init__(self, ident: Identifiability):
        self.ident, self.c, self.names = ident, ident.context, ident.names

    def label(self, i: int) -> str:
        desc = self.c.descriptions.get(self.names[i], "")
        return f"{self.names[i]} ({desc})" if desc else self.names[i]

    def amount(self, i: int, value: float) -> str:
        """A difference of parameter i in its unit (levels in cm below 1 m)."""
        unit = self.c.units.get(self.names[i], "")
        if unit in ("m AD", "m", "m NAP"):
            return f"{100 * value:.2g} cm" if abs(value) < 1 else f"{value:.3g} m"
        if unit.strip() in ("-", "1"):  # dimensionless (an imported model's friction factor): no unit after it
            return f"{value:.3g}"
        return f"{value:.3g} {unit}".strip()

    def station(self, st: str) -> str:
        what = self.c.stations.get(st)
        return f"station {st}, which measures {what}," if what else f"station {st}"

    def where(self, i: int, *, little: bool = False) -> str:
        """Which station sees parameter i (the share of its squared sensitivity)."""
        series = self.ident.series_shares[i] if self.ident.series_shares else {}
        if not series:
            return ""
        stations = station_shares(self.ident, i)
        top = max(stations, key=lambda st: (stations[st], st))
        in_top = {sid: f for sid, f in series.items() if sid.rpartition(".")[0] == top or sid == top}
        top_series = max(in_top, key=lambda sid: (in_top[sid], sid))
        mostly = f"mostly in {top_series}" if len(in_top) > 1 else top_series
        signal = "its small signal" if little else "its signal"
        if top in self.c.at.get(self.names[i], ()):
            return f"station {top} measures right at this weir ({_pct(stations[top])} of {signal}, {mostly})"
        if stations[top] >= 0.5:
            return f"{_pct(stations[top])} of {signal} is at {self.station(top)} {mostly}"
        ranked = sorted(stations.items(), key=lambda kv: (-kv[1], kv[0]))[:3]
        return f"{signal} is spread over several stations (" + ", ".join(
            f"{st} {_pct(f)}" for st, f in ranked) + ")"

    def parameter(self, i: int) -> str:
        row = self.ident.verdict.iloc[i]
        verdict, ident = row["verdict"], row["index"]
        if verdict == IDENTIFIABLE:
            text = f"{self.label(i)} is identifiable (identifiability index {ident:.2f})"
            where = self.where(i)
            text += f": {where}" if where else ""
            if math.isfinite(row["std"]):
                text += f". With the observation errors it is determined to ±{self.amount(i, row['std'])}"
            mixed = self.ident.mixed_with(i)
            if mixed:
                text += (f". Its effect is mixed with that of {_and(mixed)} in the best-seen directions, but these "
                         "are all seen clearly, so the observations still separate them")
            return text + "."
        if verdict == NOT_IDENTIFIABLE:
            return self.unseen(i, row)
        return self.combination(i, row)

    def unseen(self, i: int, row: pd.Series) -> str:
        strength = self.ident.strength([i])
        text = f"{self.label(i)} is not identifiable (identifiability index {row['index']:.2f}): "
        if strength == 0.0:
            return text + "no observation changes at all when it changes. Keep it at its current value."
        if self.ident.extra.get("unseen"):  # no parameter is seen: a share of the best-seen says nothing
            sd = f" (σ ±{self.amount(i, row['std'])})" if math.isfinite(row["std"]) else ""
            return text + (f"moving it over {self.ident.scale_name} ({self.amount(i, self.ident.scale[i])}) changes "
                           f"the misfit by less than one observation error{sd}: the observations in this window "
                           "hardly depend on it, nor on any other parameter analysed. Keep it at its current value, "
                           "or choose a window or measurements that it changes.")
        text += (f"moving it over {self.ident.scale_name} ({self.amount(i, self.ident.scale[i])}) is seen only "
                 f"{_pct(strength)} as strongly as the best-seen parameter combination")
        if math.isfinite(row["effect"]):
            text += f" and changes the observed levels by at most about {_level(row['effect'])}"
        where = self.where(i, little=True)
        if where and self.names[i] not in self.c.at:
            text += f". No station measures at this weir; {where}"
        elif where:
            text += f"; even so, {where}"
        return text + ". Keep it at its current value, or add a measurement near it."

    def combination(self, i: int, row: pd.Series) -> str:
        partners = [p for p in str(row["partners"]).split(", ") if p]
        text = f"{self.label(i)} is identifiable only in combination"
        text += f" with {', '.join(partners)}" if partners else ""
        text += f" (identifiability index {row['index']:.2f})"
        j = self.ident.shared_weak_vector(i)
        if j is not None:
            return text + ": " + self.direction(j) + "."
        if row["correlated_with"]:
            return (text + f": its effect on the stations resembles that of {row['correlated_with']} "
                    f"(correlation {row['max_correlation']:+.2f}), so the observations fix only a mix of the two.")
        return text + f": only {_pct(row['index'])} of it lies in the combinations the observations see."

    def direction(self, j: int) -> str:
        """Describe singular vector j as a change of parameters that the stations hardly notice."""
        ident = self.ident
        vj = ident.vectors[:, j]
        members = [q for q in np.argsort(-vj, kind="stable") if vj[q] ** 2 >= ident.options.loading]
        c = 0.1 / max(abs(vj[q]) for q in members)  # the largest move: 10 % of that parameter's scale
        moves = []
        for q in members:
            delta = c * vj[q] * ident.scale[q]
            moves.append(f"{'raising' if delta > 0 else 'lowering'} {self.names[q]} by {self.amount(q, abs(delta))}")
        s = ident.singular_values
        rel = s[j] / s[0] if s[0] > 0 else 0.0
        together = moves[0] + "".join(f" together with {m}" for m in moves[1:])
        return (f"{together} changes what the stations measure hardly at all (singular vector {j + 1}, seen "
                f"{_pct(rel)} as strongly as the best-seen combination), so the observations cannot tell them apart")
