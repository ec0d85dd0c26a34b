"""Engine state (hot start); the simulation results live in :mod:`rivercal.results` (imported here too)."""

from __future__ import annotations

import io
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from rivercal.engine.kernels.codes import CONTROL_STATS
from rivercal.results import Shortfall, SimulationResult, VolumeBalance

__all__ = ["EngineState", "Shortfall", "SimulationResult", "VolumeBalance"]


@dataclass
class EngineState:
    """Everything needed to continue a run exactly where it stopped.

    Attributes
    ----------
    time
        Simulated time of the state (UTC).
    z
        Levels at the h-points, m AD.
    dz
        Level change over the last step at the h-points, m (the engine extrapolates with it).
    vol
        Volumes at the h-points, m³.
    u
        Velocities at the links, m/s.
    q
        Discharges at the links, m³/s.
    pump_on
        Pump switches (0 off, 1 on).
    signature
        Grid signature (h-points, links) of the network that produced the state.
    ctl
        The controllers' state, one row per controller (:mod:`rivercal.engine.kernels.control`: integral in
        m·s, last error in m, crest in m AD, time since the last action in s, target crest in m AD, started);
        no rows for a network without controllers.
    control
        The step control's state (:data:`rivercal.engine.kernels.codes.CONTROL_STATS`: sub-step levels and their
        counters), so that a run continued from the state divides its steps as the whole run would; zeros for a
        cold start.
    flicker, swing
        Per h-point, the flicker detector's count and the level's change since it last turned, m.
    dikes
        Per summer dike whose storage changes curve (:class:`~rivercal.engine.compile.DikeArrays`), 1 while it
        drains by its falling curve, else 0; None for a network without such dikes or a cold start (all rising).
    """

    time: pd.Timestamp
    z: np.ndarray
    dz: np.ndarray
    vol: np.ndarray
    u: np.ndarray
    q: np.ndarray
    pump_on: np.ndarray
    signature: tuple[int, int]
    ctl: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    control: np.ndarray = field(default_factory=lambda: np.zeros(len(CONTROL_STATS), dtype=np.int64))
    flicker: np.ndarray | None = None
    swing: np.ndarray | None = None
    dikes: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.flicker is None:
            self.flicker = np.zeros(np.shape(self.z), dtype=np.int32)
        if self.swing is None:
            self.swing = np.zeros(np.shape(self.z))

    def dike_curves(self, n: int) -> np.ndarray:
        """A copy of :attr:`dikes` for a network with ``n`` such dikes (all rising where the state holds none)."""
        if self.dikes is None or np.size(self.dikes) != n:
            return np.zeros(n, dtype=np.int8)
        return np.asarray(self.dikes, dtype=np.int8).copy()

    def copy(self) -> EngineState:
        """A deep copy (the engine updates states in place)."""
        return EngineState(
            time=self.time,
            z=self.z.copy(),
            dz=self.dz.copy(),
            vol=self.vol.copy(),
            u=self.u.copy(),
            q=self.q.copy(),
            pump_on=self.pump_on.copy(),
            signature=self.signature,
            ctl=self.ctl.copy(),
            control=self.control.copy(),
            flicker=self.flicker.copy(),
            swing=self.swing.copy(),
            dikes=None if self.dikes is None else self.dikes.copy(),
        )

    #: Format tag of :meth:`to_bytes` (stored with the bytes so a later rivercal can tell what it reads).
    BYTES_FORMAT = "rivercal-engine-state-npz-1"

    def to_bytes(self) -> bytes:
        """The state as bytes (an ``.npz`` archive of plain arrays; no pickle), for the on-line store."""
        buffer = io.BytesIO()
        np.savez(buffer, time_ns=np.int64(self.time.value), z=self.z, dz=self.dz, vol=self.vol, u=self.u, q=self.q,
                 pump_on=self.pump_on, signature=np.asarray(self.signature, dtype=np.int64), ctl=self.ctl,
                 control=self.control, flicker=self.flicker, swing=self.swing,
                 **({} if self.dikes is None else {"dikes": self.dikes}))
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, fmt: str = BYTES_FORMAT) -> EngineState:
        """Read a state written by :meth:`to_bytes`.

        Raises
        ------
        ValueError
            For another format tag or bytes that are not such an archive.
        """
        if fmt != cls.BYTES_FORMAT:
            raise ValueError(f"engine state format {fmt!r} is not {cls.BYTES_FORMAT!r}")
        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as f:
                return cls(time=pd.Timestamp(int(f["time_ns"]), tz="UTC"), z=f["z"], dz=f["dz"], vol=f["vol"],
                           u=f["u"], q=f["q"], pump_on=f["pump_on"],
                           signature=tuple(int(v) for v in f["signature"]),  # type: ignore[arg-type]
                           ctl=f["ctl"] if "ctl" in f.files else np.zeros((0, 6)),
                           control=f["control"] if "control" in f.files else np.zeros(len(CONTROL_STATS),
                                                                                        dtype=np.int64),
                           flicker=f["flicker"] if "flicker" in f.files else None,
                           swing=f["swing"] if "swing" in f.files else None,
                           dikes=f["dikes"] if "dikes" in f.files else None)
        except (OSError, KeyError, ValueError) as exc:
            raise ValueError(f"not an engine state archive ({exc})") from None
