"""Twin experiments (layer 7): truth → simulated observations → noise → perturbed start → calibration.

Thesis §4-2-3: observations are made by the model itself with known ("true") parameters, so that a
calibration can be judged by how well it finds them back. :mod:`~rivercal.twin.practical` adds the truths
of thesis chapter 5, whose parameters change suddenly on 2010-11-01.
"""

from rivercal.twin.noise import NOISE_MODELS, add_noise
from rivercal.twin.practical import (
    ADJUSTABLE_WEIRS,
    CHANGE_TIME,
    PRACTICAL_SCENARIOS,
    PracticalScenario,
    PracticalTruth,
    QuantityChange,
    practical_truth,
)
from rivercal.twin.truth import TwinTruth, twin_truth

__all__ = [
    "ADJUSTABLE_WEIRS",
    "CHANGE_TIME",
    "NOISE_MODELS",
    "PRACTICAL_SCENARIOS",
    "PracticalScenario",
    "PracticalTruth",
    "QuantityChange",
    "TwinTruth",
    "add_noise",
    "practical_truth",
    "twin_truth",
]
