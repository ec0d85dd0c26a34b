"""The models of rivercal, for scripts: :func:`load_model` (a case or a ``model.toml``) and :func:`build_model`.

The adapters and the model contract live in :mod:`rivercal.models`; this module keeps the short import
path ``from rivercal.model import load_model``.
"""

from __future__ import annotations

from rivercal.models import build_model, load_model

__all__ = ["build_model", "load_model"]
