"""The one way rivercal makes HTML pages: Jinja2 templates, for the static reports and the live dashboard.

:func:`environment` gives a Jinja2 environment over the report's templates (``base.html``: the page
frame and stylesheet; ``blocks.html``: paragraphs, lists, tables, figures; ``report.html``: a report
with a table of contents) and, first, the templates of further packages (the dashboard's). Every value
a template prints is escaped (``&``, ``<``, ``>``, ``"`` and ``'``), except markup built by the
templates themselves, so no text from a store, a case or a user can inject markup.
"""

from __future__ import annotations

import functools
import html
from typing import Any

import jinja2
from markupsafe import Markup

__all__ = ["environment", "escape"]


def escape(value: Any) -> Markup:
    """Text as safe markup (``html.escape`` with quotes); markup already safe is kept as it is."""
    if isinstance(value, Markup) or hasattr(value, "__html__"):
        return Markup(value.__html__())
    return Markup(html.escape("" if value is None else str(value), quote=True))


@functools.cache
def environment(*packages: str) -> jinja2.Environment:
    """A Jinja2 environment over the templates of ``packages`` (searched first) and of the report.

    Parameters
    ----------
    packages
        Further packages with a ``templates`` folder, e.g. ``"rivercal.dashboard"``.
    """
    loaders = [jinja2.PackageLoader(p, "templates") for p in (*packages, "rivercal.report")]
    env = jinja2.Environment(loader=jinja2.ChoiceLoader(loaders), autoescape=True, finalize=escape,
                             undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    return env
