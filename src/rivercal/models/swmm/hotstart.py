"""SWMM's hotstart file (version 4) as arrays: node depths and link flows, read and written back.

SWMM 5.1 and 5.2 save the state of a run in a binary *hotstart file* (``SAVE HOTSTART``) that a later run
starts from (``USE HOTSTART``). Its layout is SWMM's own (EPA SWMM 5 source, ``hotstart.c``, functions
``saveRunoff``/``saveRouting``; file stamp ``SWMM5-HOTSTART4``), all numbers little-endian:

==================  =============================================================================
bytes               contents
==================  =============================================================================
15                  the stamp ``SWMM5-HOTSTART4``
6 × int32           counts of subcatchments, land uses, nodes, links, pollutants; the flow units
                    (0 CFS, 1 GPM, 2 MGD, 3 CMS, 4 LPS, 5 MLD)
runoff part         per subcatchment its runoff state (absent without subcatchments)
per node            float32 depth (ft), float32 lateral inflow (cfs), a float32 hydraulic residence
                    time for a storage node, float32 concentration per pollutant
per link            float32 flow (cfs), float32 depth (ft), float32 setting (-), float32
                    concentration per pollutant
==================  =============================================================================

SWMM keeps its hydraulics in US units internally whatever the file's flow units; depths are in ft and
flows in ft³/s (1 ft = 0.3048 m, 1 ft³/s = 0.028316846592 m³/s). Nodes and links are in the order SWMM
numbers them: the order in which the input file names them, section by section as the sections come in the
file. A run that starts from the file computes the node volumes from the depths and continues with the
link flows, depths and settings.

This module reads and writes the routing part of files without subcatchments (their runoff state has a
layout of its own per infiltration method); the runoff part of other files is refused, not guessed.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

__all__ = ["CFS", "FT", "STAMP", "Hotstart", "read_hotstart"]

#: The file stamp of version 4.
STAMP = b"SWMM5-HOTSTART4"
#: Metres per foot and m³/s per ft³/s (SWMM's internal units).
FT = 0.3048
CFS = FT**3
_HEADER = struct.Struct("<6i")


@dataclass(frozen=True)
class Hotstart:
    """The routing state of a hotstart file (module docstring).

    Attributes
    ----------
    nodes
        Per node a row: depth (ft), lateral inflow (ft³/s), [residence time], concentrations.
    links
        Per link a row: flow (ft³/s), depth (ft), setting (-), concentrations.
    header
        The six counts of the header.
    storage
        Which nodes are storage nodes (their rows hold a residence time).
    """

    nodes: list[np.ndarray]
    links: np.ndarray
    header: tuple[int, ...]
    storage: tuple[bool, ...]

    @property
    def depth_m(self) -> np.ndarray:
        """Node depths, m."""
        return np.array([row[0] for row in self.nodes], dtype=float) * FT

    @property
    def flow_m3s(self) -> np.ndarray:
        """Link flows, m³/s."""
        return self.links[:, 0].astype(float) * CFS

    def with_values(self, depth_m: np.ndarray, flow_m3s: np.ndarray) -> Hotstart:
        """The same file with these node depths (m, ≥ 0) and link flows (m³/s); everything else kept."""
        depth = np.asarray(depth_m, dtype=float)
        flow = np.asarray(flow_m3s, dtype=float)
        if depth.shape != (len(self.nodes),) or flow.shape != (self.links.shape[0],):
            raise ValueError(f"expected {len(self.nodes)} node depths and {self.links.shape[0]} link flows, got "
                             f"{depth.shape} and {flow.shape}")
        nodes = []
        for row, d in zip(self.nodes, np.maximum(depth, 0.0) / FT, strict=True):
            new = row.copy()
            new[0] = d
            nodes.append(new)
        links = self.links.copy()
        links[:, 0] = flow / CFS
        return Hotstart(nodes, links, self.header, self.storage)

    def to_bytes(self) -> bytes:
        """The file's bytes (single precision, as SWMM writes them)."""
        parts = [STAMP, _HEADER.pack(*self.header)]
        parts += [np.asarray(row, dtype="<f4").tobytes() for row in self.nodes]
        parts.append(np.asarray(self.links, dtype="<f4").tobytes())
        return b"".join(parts)


def read_hotstart(data: bytes, storage: tuple[bool, ...]) -> Hotstart:
    """A hotstart file's routing state; ``storage`` says which nodes are storage nodes (in SWMM's order).

    Raises
    ------
    ValueError
        For bytes that are no version-4 hotstart file, a file with subcatchments (whose runoff state this
        module does not read), or counts or a size that do not fit ``storage``.
    """
    if not data.startswith(STAMP) or len(data) < len(STAMP) + _HEADER.size:
        raise ValueError("not a SWMM hotstart file of version 4 (stamp SWMM5-HOTSTART4)")
    header = _HEADER.unpack_from(data, len(STAMP))
    n_sub, _, n_nodes, n_links, n_pollut, _ = header
    if n_sub:
        raise ValueError(f"the hotstart file holds {n_sub} subcatchments, whose runoff state rivercal does not read")
    if n_nodes != len(storage):
        raise ValueError(f"the hotstart file holds {n_nodes} nodes, the model {len(storage)}")
    node_size = [2 + int(s) + n_pollut for s in storage]
    link_size = 3 + n_pollut
    expected = len(STAMP) + _HEADER.size + 4 * (sum(node_size) + n_links * link_size)
    if len(data) != expected:
        raise ValueError(f"the hotstart file has {len(data)} bytes; its counts make {expected}")
    values = np.frombuffer(data, dtype="<f4", offset=len(STAMP) + _HEADER.size)
    nodes, at = [], 0
    for size in node_size:
        nodes.append(values[at:at + size].copy())
        at += size
    links = values[at:].reshape(n_links, link_size).copy()
    return Hotstart(nodes, links, tuple(header), tuple(storage))
