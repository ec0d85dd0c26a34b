"""Twin experiments (layer 7): truth → simulated observations → noise → perturbed start → calibration.

Thesis §4-2-3: observations are made by the model itself with known ("true") parameters, so that a
calibration can be judged by how well it finds them back.
"""

from rivercal.twin.noise import NOISE_MODELS, add_noise
from rivercal.twin.truth import TwinTruth, twin_truth

__all__ = ["NOISE_MODELS", "TwinTruth", "add_noise", "twin_truth"]
