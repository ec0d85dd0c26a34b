"""The real models and data of ../shared/data, found relative to the repository root.

They stay in the shared folder (their licences, e.g. LGPL for the Dellen model, keep them out of the
repository); CI requires them, so a missing folder fails the test with a message, never a silent skip.
"""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def shared_model(folder: str, *parts: str) -> Path:
    """The path of a file of a shared data folder; fails the test when it is missing."""
    path = SHARED.joinpath(folder, *parts)
    if not path.exists():
        pytest.fail(f"the shared data {path} is missing: the tests read the real D-HYDRO models from "
                    f"../shared/data beside the repository (copy /work/shared there)", pytrace=False)
    return path
