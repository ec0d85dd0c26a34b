"""The calibration problem: model + parameters + observations → weighted residuals, and its calibration.

- :mod:`~rivercal.problem.residuals`: :class:`CalibrationProblem` (the residuals of thesis Eq. 2-3, weights,
  warm-up, failure policy, batches through the model's batch runs) and :class:`CostBreakdown`;
- :mod:`~rivercal.problem.loss`: the robust costs (Huber, Student-t);
- :mod:`~rivercal.problem.fit`: :func:`calibrate` (an optimiser on a problem, with the problem's defaults) and
  :func:`problem_evaluator`;
- :mod:`~rivercal.problem.outcome`: :class:`Calibration`, what a calibration gives (estimates, σ, history,
  fit report).

The problem sees a model only through the model contract (:mod:`rivercal.models.contract`).
"""

from rivercal.models.contract import Model
from rivercal.problem.fit import calibrate, problem_evaluator
from rivercal.problem.loss import LOSSES, STUDENT_T_DOF, robust_residuals
from rivercal.problem.outcome import Calibration
from rivercal.problem.residuals import CalibrationProblem, CostBreakdown

__all__ = ["LOSSES", "STUDENT_T_DOF", "Calibration", "CalibrationProblem", "CostBreakdown", "Model", "calibrate",
           "problem_evaluator", "robust_residuals"]
