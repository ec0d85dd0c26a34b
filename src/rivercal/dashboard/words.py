"""The dashboard's words: what a parameter sets, what a quantity is, and the service's decisions.

The decisions and alerts are named as in the glossary of the documentation
(``docs/explanation/alerts-and-decisions.md``): *accepted*, *held*, *jump*, *transition*, *jump alert*,
*fallback*. The short definitions here are the glossary's, shortened for a tooltip.
"""

from __future__ import annotations

from typing import Any

from rivercal._format import plural

__all__ = ["ALERT_NAMES", "DECISIONS", "describe_parameter", "describe_series"]

#: The glossary's decisions, each in one sentence (tooltips and the legend of the "Now" page).
DECISIONS = {
    "accepted": "the cycle took its estimate as the parameter's value; the next cycle starts from it and "
                "rivercal's forecast uses it",
    "held": "the cycle did not take its estimate: the parameter keeps its last accepted value (the reason "
            "is given)",
    "jump": "an estimate moved by more than its resolution and more than k σ; it starts the transition "
            "estimator and raises no alert by itself",
    "transition": "a change of a parameter inside the window (value before, value after, time) that the "
                  "transition estimator found after a jump",
    "jump alert": "a probable intervention: raised once, by the cycle that found a transition",
    "fallback": "the cycle issued the DSS's forecast instead of rivercal's, because rivercal's recent "
                "forecasts scored worse (the first cycles, before anything was scored, issue the DSS's too; "
                "that is no fallback)",
}

#: How an alert kind of the store is called on the pages.
ALERT_NAMES = {"jump": "jump alert", "limit": "limit alert", "data": "data alert"}

_QUANTITY = {"h": "level", "h_up": "level upstream", "h_down": "level downstream", "Q": "discharge"}


def describe_series(series: str) -> str:
    """``"0028.h_up"`` → ``"0028, level upstream"`` (the quantity in words)."""
    station, _, quantity = series.rpartition(".")
    return f"{station}, {_QUANTITY.get(quantity, quantity)}"


def _target(name: str) -> str:
    if name == "friction:global":
        return "bed friction of the whole network"
    if name == "friction:scale":
        return "factor on all bed friction"
    for prefix, words in (("friction:branch:", "bed friction of branch "), ("friction:group:", "bed friction of "
                                                                                                 "group ")):
        if name.startswith(prefix):
            return words + name.removeprefix(prefix)
    if name.startswith("weir:") and name.endswith(".crest_level"):
        return f"crest level of weir {name.removeprefix('weir:').removesuffix('.crest_level')}"
    if name.startswith("control:"):
        ident, _, what = name.removeprefix("control:").partition(".")
        return f"{what.replace('_', ' ')} of controller {ident}"
    return name


def describe_parameter(parameter: Any) -> str:
    """What a calibration parameter sets, in words.

    E.g. ``"bed friction of the whole network"``, ``"common shift of the crests of 9 weirs"``.
    """
    cluster = list(getattr(parameter, "cluster", []) or [])
    if cluster:
        weirs = all(c.target.startswith("weir:") for c in cluster)
        things = plural(len(cluster), "weir") if weirs else plural(len(cluster), "quantity", "quantities")
        if getattr(parameter, "cluster_mode", "fraction") == "shift":
            return f"common shift of the crests of {things}" if weirs else f"common shift of {things}"
        return (f"crest levels of {things}, as a share of their ranges" if weirs
                else f"{things}, as a share of their ranges")
    targets = list(getattr(parameter, "targets", []) or [])
    if not targets:
        return ""
    return _target(targets[0]) + (f" and {len(targets) - 1} more" if len(targets) > 1 else "")
