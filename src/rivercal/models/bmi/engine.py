"""The embedded engine as a Basic Model Interface component (bmipy), so that BMI frameworks can drive it.

``initialize(config_file)`` reads a small TOML file::

    case = "dommel"                       # a case folder (relative to the file) or a packaged case
    start = "2010-10-01T00:00:00Z"        # optional: the period (default: the case's); cold start here
    end = "2010-10-08T00:00:00Z"

Time is in seconds since ``start``; ``update`` advances one engine step (``dt``), ``update_until`` whole
steps up to the given time (the last step that ends at or before it). The state at ``start`` is the
engine's cold start there (rest, then the case's spin-up with the case's own crests and friction).

Grids: 0 is the network, ``unstructured`` with the calculation points as nodes (x, y in m) and the links
between them as edges; 1 holds the weirs, 2 the branches and 3 the inflows and laterals, each an
``unstructured`` grid of nodes without edges (a weir at the middle of its link, a branch at the mean of its
links' middles, an inflow or lateral at the point where it enters).

Variables (float64):

==============================================  ======  ====  =====  =========================================
name                                            units   grid  where  role
==============================================  ======  ====  =====  =========================================
``channel_water_surface__elevation``            m       0     node   level (m AD); in and out (a state)
``channel_water__volume``                       m3      0     node   stored volume; in and out (a state)
``channel_water_surface__elevation_increment``  m       0     node   level change of the last step (a state)
``channel_water__volume_flow_rate``             m3 s-1  0     edge   discharge; in and out (a state)
``channel_water_flow__speed``                   m s-1   0     edge   velocity; in and out (a state)
``weir_crest__elevation``                       m       1     node   crest levels (m AD); in and out
``channel_bed__friction_coefficient``           (law)   2     node   friction values; in and out
``channel_inflow__multiplier``                  1       3     node   factor on each inflow and lateral (1: the
                                                                     case's); in and out
``channel_bottom_surface__elevation``           m       0     node   lowest bed level at the point; out
==============================================  ======  ====  =====  =========================================

The friction unit is that of the case's friction law (k_s: ``m1/3 s-1``); a branch with its own law
carries that law's value. Setting the levels sets the matching volumes too, and setting the discharges the
velocities (each link keeps its flow area; a link at rest keeps its velocity); a framework that restores a
whole state sets all five state variables after them, as :class:`~rivercal.models.bmi.BmiModel` does, and
gets them exactly. Pumps' on/off switches are not exposed (a hot start through BMI restarts them off).
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from bmipy import Bmi

from rivercal.models.contract import utc
from rivercal.models.embedded import EmbeddedModel, load_case_model
from rivercal.network import FRICTION_RANGES

__all__ = ["RivercalBmi"]

LEVEL = "channel_water_surface__elevation"
VOLUME = "channel_water__volume"
LEVEL_CHANGE = "channel_water_surface__elevation_increment"
DISCHARGE = "channel_water__volume_flow_rate"
VELOCITY = "channel_water_flow__speed"
CREST = "weir_crest__elevation"
FRICTION = "channel_bed__friction_coefficient"
INFLOW_FACTOR = "channel_inflow__multiplier"
BED = "channel_bottom_surface__elevation"
#: name → (state attribute or parameter, grid, location, units)
_VARS = {
    LEVEL: ("z", 0, "node", "m"), VOLUME: ("vol", 0, "node", "m3"), LEVEL_CHANGE: ("dz", 0, "node", "m"),
    DISCHARGE: ("q", 0, "edge", "m3 s-1"), VELOCITY: ("u", 0, "edge", "m s-1"),
    CREST: ("crest", 1, "node", "m"), FRICTION: ("friction", 2, "node", ""), INFLOW_FACTOR: ("factor", 3, "node", "1"),
    BED: ("bed", 0, "node", "m"),
}
#: Variables that are outputs only.
_OUTPUT_ONLY = (BED,)
#: The models this process loaded, by case, and their cold-start states, by case and start (the same for
#: every run: the case's spin-up with its own crests and friction).
_MODELS: dict[str, EmbeddedModel] = {}
_STARTS: dict[tuple[str, pd.Timestamp], Any] = {}
_UNITS = {"m^(1/3)/s": "m1/3 s-1", "s/m^(1/3)": "s m-1/3", "m^(1/2)/s": "m1/2 s-1"}


class RivercalBmi(Bmi):
    """The embedded engine behind BMI 2.0 (module docstring)."""

    def __init__(self) -> None:
        self._model: EmbeddedModel | None = None
        self._state = None
        self._time = 0.0

    # -- control --------------------------------------------------------------------------------------

    def initialize(self, config_file: str) -> None:
        """Load the case of ``config_file`` and cold-start it at the configured start."""
        path = Path(config_file)
        config = tomllib.loads(path.read_text(encoding="utf-8"))
        source = config.get("case")
        if not isinstance(source, str):
            raise ValueError(f"{path}: 'case' must name a case folder or a packaged case")
        folder = path.parent / source
        key = str(folder.resolve()) if folder.is_dir() else source
        if key not in _MODELS:  # one compiled model per case and process: a framework initializes many runs
            _MODELS[key] = load_case_model(folder if folder.is_dir() else source)
        model = _MODELS[key]
        self._model = model
        self._start = utc(config["start"]) if "start" in config else model.start
        self._end = utc(config["end"]) if "end" in config else model.end
        if not model.start <= self._start < self._end <= model.end:
            raise ValueError(f"{path}: the period {self._start} .. {self._end} is not inside the case's "
                             f"{model.start} .. {model.end}")
        self._crest, self._friction = (a.copy() for a in model.parameter_arrays(None))
        self._factor = np.ones(len(model.perturbable_forcing()))
        self._bed = np.array(model.compiled.arrays.hp_bed, dtype=float)
        if (key, self._start) not in _STARTS:
            _STARTS[(key, self._start)] = model.start_state(self._start)
        self._state = _STARTS[(key, self._start)].copy()
        self._time = 0.0

    def update(self) -> None:
        """Advance one engine step."""
        self._advance(1)

    def update_until(self, time: float) -> None:
        """Advance whole steps up to ``time`` (s since start; the last step that ends at or before it)."""
        steps = int(np.floor((float(time) - self._time) / self._model.dt + 1e-9))
        if steps > 0:
            self._advance(steps)

    def _advance(self, steps: int) -> None:
        model = self._model
        now = self._start + pd.Timedelta(seconds=self._time)
        end = now + pd.Timedelta(seconds=steps * model.dt)
        if end > self._end:
            raise ValueError(f"cannot advance past the end of the period ({self._end})")
        quantities = self._quantities()
        self._state.time = now
        if np.all(self._factor == 1.0):
            _, new = model.simulate(quantities, start=now, end=end, state=self._state, output_interval=model.dt * steps)
        else:  # the inflows and laterals scaled by their factors
            _, new = model.simulate_perturbed(quantities, now, end, self._state, self._factor[None],
                                              steps * model.dt, output_interval=model.dt * steps)
        for attr in ("z", "dz", "vol", "u", "q", "pump_on"):
            np.copyto(getattr(self._state, attr), getattr(new, attr))  # keep the arrays of get_value_ptr
        self._state.time = end
        self._time += steps * model.dt

    def _quantities(self) -> dict[str, float]:
        c = self._model.compiled
        out = {f"weir:{w}.crest_level": float(v) for w, v in zip(c.weir_ids, self._crest, strict=True)}
        out.update({f"friction:branch:{b}": float(v) for b, v in zip(c.branch_ids, self._friction, strict=True)})
        return out

    def finalize(self) -> None:
        """Release the model."""
        self._model = None
        self._state = None

    # -- information ----------------------------------------------------------------------------------

    def get_component_name(self) -> str:
        """The component's name."""
        return "rivercal embedded 1D network engine"

    def get_input_item_count(self) -> int:
        """Number of input variables."""
        return len(_VARS) - len(_OUTPUT_ONLY)

    def get_output_item_count(self) -> int:
        """Number of output variables."""
        return len(_VARS)

    def get_input_var_names(self) -> tuple[str, ...]:
        """Names of the input variables."""
        return tuple(v for v in _VARS if v not in _OUTPUT_ONLY)

    def get_output_var_names(self) -> tuple[str, ...]:
        """Names of the output variables."""
        return tuple(_VARS)

    # -- variables ------------------------------------------------------------------------------------

    def _array(self, name: str) -> np.ndarray:
        if name not in _VARS:
            raise KeyError(f"unknown BMI variable {name!r}; have {', '.join(_VARS)}")
        attr = _VARS[name][0]
        if attr == "crest":
            return self._crest
        if attr == "friction":
            return self._friction
        if attr == "factor":
            return self._factor
        if attr == "bed":
            return self._bed
        return getattr(self._state, attr)

    def get_var_grid(self, name: str) -> int:
        """Grid of a variable."""
        self._array(name)
        return _VARS[name][1]

    def get_var_type(self, name: str) -> str:
        """NumPy type of a variable."""
        return str(self._array(name).dtype)

    def get_var_units(self, name: str) -> str:
        """Units of a variable (UDUNITS spelling)."""
        self._array(name)
        if name == FRICTION:
            unit = FRICTION_RANGES[self._model.case.spec.friction.type][2]
            return _UNITS.get(unit, unit)
        return _VARS[name][3]

    def get_var_itemsize(self, name: str) -> int:
        """Bytes per element."""
        return int(self._array(name).itemsize)

    def get_var_nbytes(self, name: str) -> int:
        """Bytes of the whole variable."""
        return int(self._array(name).nbytes)

    def get_var_location(self, name: str) -> str:
        """``node`` or ``edge``."""
        self._array(name)
        return _VARS[name][2]

    # -- time -----------------------------------------------------------------------------------------

    def get_current_time(self) -> float:
        """Seconds since start."""
        return float(self._time)

    def get_start_time(self) -> float:
        """0 (time counts from the configured start)."""
        return 0.0

    def get_end_time(self) -> float:
        """Seconds from start to end."""
        return float((self._end - self._start).total_seconds())

    def get_time_units(self) -> str:
        """Seconds."""
        return "s"

    def get_time_step(self) -> float:
        """The engine's time step, s."""
        return float(self._model.dt)

    # -- values ---------------------------------------------------------------------------------------

    def get_value(self, name: str, dest: np.ndarray) -> np.ndarray:
        """Copy a variable into ``dest``."""
        dest[:] = self._array(name).ravel()
        return dest

    def get_value_ptr(self, name: str) -> np.ndarray:
        """The variable's own array (stays valid across updates)."""
        return self._array(name)

    def get_value_at_indices(self, name: str, dest: np.ndarray, inds: np.ndarray) -> np.ndarray:
        """Copy the elements ``inds`` of a variable into ``dest``."""
        dest[:] = self._array(name)[np.asarray(inds, dtype=int)]
        return dest

    def set_value(self, name: str, src: np.ndarray) -> None:
        """Set a whole variable (levels set the volumes, discharges the velocities: module docstring)."""
        array = self._writable(name)
        old = array.copy()
        array[:] = np.asarray(src, dtype=float).reshape(array.shape)
        self._follow(name, old)

    def set_value_at_indices(self, name: str, inds: np.ndarray, src: np.ndarray) -> None:
        """Set the elements ``inds`` of a variable."""
        array = self._writable(name)
        old = array.copy()
        array[np.asarray(inds, dtype=int)] = np.asarray(src, dtype=float)
        self._follow(name, old)

    def _writable(self, name: str) -> np.ndarray:
        if name in _OUTPUT_ONLY:
            raise KeyError(f"BMI variable {name!r} is an output only")
        return self._array(name)

    def _follow(self, name: str, old: np.ndarray) -> None:
        """After levels: their volumes; after discharges: the velocities at the links' flow areas."""
        from rivercal.engine.kernels.batch import volumes

        s = self._state
        if name == LEVEL:
            volumes(self._model.compiled.arrays, s.z, s.vol)
        elif name == DISCHARGE:
            with np.errstate(divide="ignore", invalid="ignore"):
                area = np.where(np.abs(s.u) > 1e-9, old / s.u, np.nan)
            moving = np.isfinite(area) & (area > 0)
            s.u[:] = np.where(moving, s.q / area, s.u)

    # -- grids ----------------------------------------------------------------------------------------

    def _grid_xy(self, grid: int) -> np.ndarray:
        c = self._model.compiled
        a = c.arrays
        if grid == 0:
            return c.hp_xy
        if grid == 1:
            links = [c.structure_link[w] for w in c.weir_ids]
            return 0.5 * (c.hp_xy[a.lk_k1[links]] + c.hp_xy[a.lk_k2[links]])
        if grid == 2:
            mids = 0.5 * (c.hp_xy[a.lk_k1] + c.hp_xy[a.lk_k2])
            on = np.asarray(c.link_branch)
            return np.array([mids[on == b].mean(axis=0) for b in c.branch_ids])
        if grid == 3:
            places = self._model.state_layout().forcing_places
            return np.array([c.hp_xy[places[k]] for k in self._model.perturbable_forcing()]).reshape(-1, 2)
        raise KeyError(f"unknown grid {grid} (grids 0, 1, 2, 3)")

    def get_grid_rank(self, grid: int) -> int:
        """2 (x, y) for every grid."""
        self._grid_xy(grid)
        return 2

    def get_grid_size(self, grid: int) -> int:
        """Number of nodes."""
        return int(self._grid_xy(grid).shape[0])

    def get_grid_type(self, grid: int) -> str:
        """``unstructured`` for every grid."""
        self._grid_xy(grid)
        return "unstructured"

    def get_grid_x(self, grid: int, x: np.ndarray) -> np.ndarray:
        """The x of the nodes, m."""
        x[:] = self._grid_xy(grid)[:, 0]
        return x

    def get_grid_y(self, grid: int, y: np.ndarray) -> np.ndarray:
        """The y of the nodes, m."""
        y[:] = self._grid_xy(grid)[:, 1]
        return y

    def get_grid_z(self, grid: int, z: np.ndarray) -> np.ndarray:
        """Bed level of the network's nodes (m AD); zeros for the other grids (rank 2)."""
        z[:] = self._model.compiled.arrays.hp_bed if grid == 0 else 0.0
        return z

    def get_grid_node_count(self, grid: int) -> int:
        """Number of nodes."""
        return self.get_grid_size(grid)

    def get_grid_edge_count(self, grid: int) -> int:
        """Links of the network; 0 for the weir and branch grids."""
        self._grid_xy(grid)
        return int(self._model.compiled.arrays.lk_k1.size) if grid == 0 else 0

    def get_grid_face_count(self, grid: int) -> int:
        """0: a network has no faces."""
        self._grid_xy(grid)
        return 0

    def get_grid_edge_nodes(self, grid: int, edge_nodes: np.ndarray) -> np.ndarray:
        """The two nodes of every edge, flattened."""
        if grid == 0:
            a = self._model.compiled.arrays
            edge_nodes[:] = np.column_stack([a.lk_k1, a.lk_k2]).ravel()
        return edge_nodes

    def get_grid_face_edges(self, grid: int, face_edges: np.ndarray) -> np.ndarray:
        """No faces: nothing to fill."""
        return face_edges

    def get_grid_face_nodes(self, grid: int, face_nodes: np.ndarray) -> np.ndarray:
        """No faces: nothing to fill."""
        return face_nodes

    def get_grid_nodes_per_face(self, grid: int, nodes_per_face: np.ndarray) -> np.ndarray:
        """No faces: nothing to fill."""
        return nodes_per_face

    def get_grid_shape(self, grid: int, shape: np.ndarray) -> np.ndarray:
        """Not defined for unstructured grids."""
        raise NotImplementedError("get_grid_shape: the grids are unstructured")

    def get_grid_spacing(self, grid: int, spacing: np.ndarray) -> np.ndarray:
        """Not defined for unstructured grids."""
        raise NotImplementedError("get_grid_spacing: the grids are unstructured")

    def get_grid_origin(self, grid: int, origin: np.ndarray) -> np.ndarray:
        """Not defined for unstructured grids."""
        raise NotImplementedError("get_grid_origin: the grids are unstructured")
