"""rivercal: keep river-network models honest while they are in use.

The package contains an embedded 1D De Saint-Venant network engine (staggered Delft scheme,
compiled with numba), a calibration core and an on-line parameter-estimation service. Importing
``rivercal`` is cheap: the engine, pandas and matplotlib are loaded only by the modules that need
them.
"""

from __future__ import annotations

import logging

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())
