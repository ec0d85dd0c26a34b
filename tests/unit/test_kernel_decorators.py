"""Kernels compiled for calls from other kernels only refuse a call from Python with a clear error."""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.engine.kernels import fluxes
from rivercal.engine.kernels._jit import InnerKernel


def test_an_inner_kernel_called_from_python_raises_instead_of_crashing() -> None:
    assert isinstance(fluxes.check_levels, InnerKernel)
    with pytest.raises(TypeError, match=r"fluxes\.check_levels is compiled for calls from other kernels only"):
        fluxes.check_levels(np.zeros(3), np.zeros(3))

