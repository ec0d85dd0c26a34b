"""Kernels for ensembles of the engine.

The members themselves run the single-run time loop (:mod:`rivercal.engine.ensemble`).
"""

from __future__ import annotations

from rivercal.engine.kernels._jit import entry
from rivercal.engine.kernels.lookup import hp_volume_width

__all__ = ["volumes"]


@entry
def volumes(net, z, vol):
    """The volume (m³) at every h-point for levels ``z`` (m AD), into ``vol`` (e.g. after a state analysis)."""
    for i in range(z.size):
        vol[i] = hp_volume_width(net.sc_ptr, net.sc_prof, net.sc_bed, net.sc_len, net.hp_bed, net.hp_amin,
                                 net.tab_off, net.tab_n, net.tab_dd, net.tab_idd, net.tab_top, net.tab_wt_top,
                                 net.tab_at, net.tab_wt, i, z[i])[0]
