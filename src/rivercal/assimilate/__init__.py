"""Data assimilation over ensembles of model states (layer 6; numerics only, no I/O).

:mod:`.filters` — the stochastic EnKF and the ETKF analyses with localisation and inflation;
:mod:`.localisation` — the Gaspari–Cohn taper and distances along a network;
:mod:`.perturb` — model error: AR(1) perturbations of inflows and laterals in time.
"""

from rivercal.assimilate.filters import FILTERS, enkf_analysis, etkf_analysis
from rivercal.assimilate.localisation import gaspari_cohn, network_distances

__all__ = ["FILTERS", "enkf_analysis", "etkf_analysis", "gaspari_cohn", "network_distances"]
