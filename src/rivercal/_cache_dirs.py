"""The user's cache folder of rivercal: where the compiled kernels and the spun-up states are kept."""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["user_cache"]


def user_cache(name: str) -> Path | None:
    """``$XDG_CACHE_HOME/rivercal/<name>``, else ``~/.cache/rivercal/<name>``; None without a home folder.

    Never a folder relative to the working directory: without ``XDG_CACHE_HOME`` and a home folder that is
    known (``HOME`` or the user's passwd entry), there is none.
    """
    base = os.environ.get("XDG_CACHE_HOME", "").strip()
    if not base:
        home = Path(os.path.expanduser("~"))
        if not home.is_absolute():
            return None
        base = str(home / ".cache")
    return Path(base) / "rivercal" / name
