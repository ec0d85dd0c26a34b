"""Tiny runtime options.

The only global state in rivercal. ``RIVERCAL_LOG_LEVEL`` is read once at import; everything else
is passed explicitly.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

__all__ = ["Options", "options"]


@dataclass(slots=True)
class Options:
    """Runtime options.

    Attributes
    ----------
    log_level
        Level name for the ``rivercal`` logger when the command line configures logging.
    """

    log_level: str = os.environ.get("RIVERCAL_LOG_LEVEL", "WARNING")


options = Options()
