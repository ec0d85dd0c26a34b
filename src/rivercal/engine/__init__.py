"""The embedded 1D De Saint-Venant network engine (layer 3).

``Simulator`` compiles a case once and runs it with parameters given as model quantities; the
time loop is one numba call per window (:mod:`rivercal.engine.kernels`).
"""

from rivercal.engine.compile import CompiledNetwork, compile_network
from rivercal.engine.quantities import parse_target
from rivercal.engine.simulator import Simulator
from rivercal.engine.state import EngineState, SimulationResult, VolumeBalance

__all__ = [
    "CompiledNetwork",
    "EngineState",
    "SimulationResult",
    "Simulator",
    "VolumeBalance",
    "compile_network",
    "parse_target",
]
