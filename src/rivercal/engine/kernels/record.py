"""The output of a run: the stations' observables and, when asked for, the full level and flux fields."""

from __future__ import annotations

from rivercal.engine.kernels._jit import kernel
from rivercal.engine.kernels.codes import OBS_LEVEL

__all__ = ["record"]


@kernel
def record(net, row, z, q, obs_out, z_out, q_out):
    """Write the observables (and, if requested, the full fields) of output row ``row``."""
    if row < obs_out.shape[0]:
        for o in range(net.ob_type.size):
            if net.ob_type[o] == OBS_LEVEL:
                w = net.ob_w[o]
                obs_out[row, o] = w * z[net.ob_i1[o]] + (1.0 - w) * z[net.ob_i2[o]]
            else:
                obs_out[row, o] = net.ob_w[o] * q[net.ob_i1[o]]
    if row < z_out.shape[0]:
        for i in range(z.size):
            z_out[row, i] = z[i]
        for link in range(q.size):
            q_out[row, link] = q[link]
