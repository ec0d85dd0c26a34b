"""Figures without pyplot: the one way rivercal's plotting functions make a figure and write it.

A :class:`matplotlib.figure.Figure` made directly is not registered with pyplot, so nothing global is
touched: the user's backend (a notebook's inline or widget backend, an interactive window) stays what
it was, and nothing has to be closed. Writing a PNG, PDF or SVG needs no backend either (matplotlib
picks the canvas by the file type). Only the command line chooses a backend. matplotlib is imported
when a figure is made, never at import time.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["iteration_axis", "new_figure", "save_figure", "subplots"]

_FIGURE_KEYWORDS = ("figsize", "dpi", "layout", "facecolor")


def new_figure(**kwargs: Any) -> Any:
    """A ``matplotlib.figure.Figure(**kwargs)`` (figsize in inches, layout …), outside pyplot."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def subplots(nrows: int = 1, ncols: int = 1, **kwargs: Any) -> tuple[Any, Any]:
    """Like ``pyplot.subplots`` but outside pyplot: (figure, axes).

    Figure keywords (``figsize``, ``dpi``, ``layout``, ``facecolor``) make the figure; the others
    (``sharex``, ``squeeze``, ``height_ratios`` …) go to :meth:`matplotlib.figure.Figure.subplots`.
    """
    fig = new_figure(**{k: kwargs.pop(k) for k in _FIGURE_KEYWORDS if k in kwargs})
    return fig, fig.subplots(nrows, ncols, **kwargs)


def save_figure(fig: Any, path: str | Path, *, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (its folder is created; the type follows the suffix) and return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    return path


def iteration_axis(ax: Any) -> None:
    """Label ``ax``'s horizontal axis "iteration", with ticks at whole iterations only."""
    from matplotlib.ticker import MaxNLocator

    ax.set_xlabel("iteration")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
