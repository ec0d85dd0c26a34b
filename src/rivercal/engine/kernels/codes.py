"""The integer codes of the kernel arrays, named once for the packing code and the kernels.

The packing code (:mod:`rivercal.engine.compile`) writes these codes into the network arrays; the
kernels compare with the same names. Numba reads a module-level integer as a compile-time constant,
so ``lk_type[link] == LINK_WEIR`` compiles to the same machine code as ``lk_type[link] == 1``.

Numba's cache checks a kernel's own source file only: after changing a value here, remove the
stale caches (``make clean-cache``).
"""

from __future__ import annotations

# -- link types (``lk_type``) ---------------------------------------------------------------------
LINK_CHANNEL = 0
LINK_WEIR = 1
LINK_CULVERT = 2
LINK_PUMP = 3
LINK_ORIFICE = 4
LINK_UNIVERSAL_WEIR = 5

# -- boundary kinds (``b_type``) ------------------------------------------------------------------
BOUNDARY_DISCHARGE = 0
BOUNDARY_LEVEL = 1
BOUNDARY_RATING = 2

# -- friction types (``fr_type``, ``lk_ftype``, ``c_ftype``) --------------------------------------
FRICTION_STRICKLER = 0
FRICTION_MANNING = 1
FRICTION_CHEZY = 2
FRICTION_WHITE_COLEBROOK = 3

# -- flow directions a structure lets through (``w_dir``, ``c_dir``) ------------------------------
FLOW_BOTH = 0
FLOW_POSITIVE = 1
FLOW_NEGATIVE = 2
FLOW_NONE = 3
#: Depth of water (m) below which a pump's suction point is dry: the pump stops, whatever its stop level.
PUMP_DRY = 0.01

# -- culvert barrel shapes (``c_shape``) ----------------------------------------------------------
CULVERT_RECTANGULAR = 0
CULVERT_CIRCULAR = 1
CULVERT_PROFILE = 2  # the shape of a profile table (a bridge, an egg-shaped or open culvert)

# -- columns of ``c_extra`` (a culvert's or bridge's second invert, expansion flag, barrel table) ---------
C_INVERT2 = 0
C_EXPAND = 1
C_PROF = 2
C_WIDTH = 3

# -- columns of ``o_par`` (an orifice) --------------------------------------------------------------
O_CREST = 0
O_SPAN = 1
O_GATE = 2
O_MU = 3
O_DIR = 4
O_QPOS = 5
O_QNEG = 6
O_WIDTH = 7

# -- columns of ``u_par`` (a universal weir) and ``u_strip`` (its crest strips) ---------------------------
U_CE = 0
U_DIR = 1
U_FIRST = 2
U_END = 3
U_WIDTH = 4
STRIP_SPAN = 0
STRIP_CREST = 1

# -- observables (``ob_type``) --------------------------------------------------------------------
OBS_LEVEL = 0
OBS_FLUX = 1

# -- the neighbour of a channel link at one end (``lk_nb1``, ``lk_nb2``), when it is not one link --
NB_JUNCTION = -1  # two or more other links meet there
NB_NONE = -2  # a branch end without another link, or a structure
NB_OUTFALL = -3  # the end at a free outfall (a critical boundary; kernels.outfall)

# -- run status of the time loop (:func:`rivercal.engine.kernels.timeloop.run`) -------------------
STATUS_OK = 0
STATUS_LEVEL = 1  # a level left the plausible range (the index is an h-point)
STATUS_VELOCITY = 2  # a velocity exceeded engine.max_velocity (the index is a link)
STATUS_DRY = 3  # a level fell below its bed by more than DRY_TOLERANCE at the smallest sub-step (h-point)
STATUS_FLICKER = 4  # a level alternated up and down from step to step at the smallest sub-step (h-point)

# -- counters of a run (``Work.stats``) -----------------------------------------------------------
STAT_STEPS = 0
STAT_SOLVES = 1
STAT_DRYING = 2
STAT_SUBSTEPS = 3  # sub-steps taken (a step divided into 2^level sub-steps counts 2^level)
STAT_REFINED = 4  # steps that were divided into sub-steps
STAT_MAX_LEVEL = 5  # the largest sub-step level used (the step divided by 2^level)
STAT_LEVEL = 6  # the sub-step level of the next step (state of the step control)
STAT_CALM = 7  # steps since the level last rose or fell
STAT_RELAX = 8  # calm steps after which the level falls by one (doubles when a fall is undone at once)
STAT_FELL = 9  # 1 while the last change of the level was a fall
STAT_AMP = 10  # the last explicit-depth amplification of the step control, in millionths (kernels.stability)
STAT_ACC = 11  # the sub-step level the accuracy control asks for this step (state of the step control)
STAT_FLICKERS = 12  # times a point's level flickered (FLICKER_LIMIT)
STAT_FLICKER_AT = 13  # the point of the last such flicker (-1: none)
STAT_REDONE = 14  # (sub-)steps computed again, shorter, because the screen refused them
STAT_ACC_NEXT = 15  # the accuracy level the last committed sub-step asks of the next step
STAT_LAST = 16  # the sub-step level of the last committed (sub-)step
STAT_EXPLICIT = 17  # (sub-)steps solved with the geometry of their start after its iterations did not converge
STAT_COURANT = 18  # the sub-step level the Courant limit asks for this step (from the state at its start)
N_STATS = 19
#: The entries of ``Work.stats`` that are the step control's state, carried from run to run in the engine state
#: (a run split in two then computes what the whole run computes).
CONTROL_STATS = (STAT_LEVEL, STAT_CALM, STAT_RELAX, STAT_FELL, STAT_AMP, STAT_ACC, STAT_ACC_NEXT, STAT_LAST)

#: Relative difference of the depths at a channel link's two ends, the downstream one the smaller, above
#: which its friction moves from the upwind depth towards their mean
#: (:func:`rivercal.engine.kernels.momentum.channel_coefficients`).
FRICTION_SPLIT = 0.01
#: ... and at or above which (a drop in the bed, a jump: no gradually varied surface) it stays upwind.
FRICTION_GRADUAL = 0.3

#: The channels' geometry at the iterate (:func:`rivercal.engine.kernels.picard.picard_iterations`): where a step
#: moves the level at a link's upwind point by less than GEOMETRY_FROM (m) the link keeps the flow area and friction
#: of the level at the step's start; from there it moves linearly to those of the iterate, which it takes from
#: GEOMETRY_FULL (m). A step of a slowly varying flow keeps the geometry of its start (and its steady state its
#: exactness); a flood wave that moves the level centimetres per step does not lag a step behind it.
GEOMETRY_FROM = 0.005
GEOMETRY_FULL = 0.01
#: ... An iteration of the geometry whose change of the levels exceeds GEOMETRY_FROM and is not below
#: GEOMETRY_CONTRACT times the one before does not converge (the geometry swings between two states): the step is
#: solved with the geometry of its start.
GEOMETRY_CONTRACT = 0.9

# -- the step control (:mod:`rivercal.engine.kernels.timeloop`) -----------------------------------
#: Most halvings of a step: a step is divided into at most 2^MAX_HALVINGS sub-steps.
MAX_HALVINGS = 14
#: A level this far below its bed (m) is not accepted: the (sub-)step is divided, or the run stops.
DRY_TOLERANCE = 0.05
#: Calm steps after which the sub-step level first falls by one again.
RELAX_STEPS = 16
#: Explicit-depth amplification (:mod:`rivercal.engine.kernels.stability`) above which a step is divided.
AMP_RISE = 1.0
#: ... and below which the sub-step level may fall again (a doubled step roughly doubles it).
AMP_FALL = 0.4
#: The accuracy control. Its error estimate of a (sub-)step is the largest difference at a point (not a level
#: boundary) between the solved level and the level extrapolated from the last (sub-)step's change at the same rate
#: (:func:`.fluxes.check_levels`): about half the curvature of the level's path times the step squared, the local
#: error of the scheme's first-order time integration. A step is sized for an estimate of ERR_TARGET (m) ...
ERR_TARGET = 0.01
#: ... and computed again, halved, above ERR_REDO (m).
ERR_REDO = 0.05
#: With a Courant limit (``engine.courant``), a solved (sub-)step whose velocities cross a link more than COURANT_REDO
#: times faster than the limit allows is computed again, shorter (the limit itself is taken at each step's start).
COURANT_REDO = 2.0
#: Flicker: a level that turns (from rising to falling, or back) after moving more than FLICKER_DZ (m) since its
#: last turn adds FLICKER_TURN to its point's count, and every (sub-)step takes one off; at FLICKER_LIMIT the point
#: flickers (:func:`.fluxes.finish_step`). Turns every step reach it at the fourth, turns every fourth step at the
#: sixth; turns FLICKER_TURN or more steps apart never do: an oscillation with a period under about twice that many
#: steps is not resolved by the step, whether the scheme or the flow started it. (Counted more tightly, 6 and 18, the
#: imported Dellen model divided fewer steps, but a steep reach at a 300 s step stopped refining before its
#: oscillation was resolved and settled 4 cm from the 5 s solution.)
FLICKER_DZ = 0.01
FLICKER_TURN = 8
FLICKER_LIMIT = 24

# -- columns of a row of ``lk_runs`` (:func:`rivercal.engine.plan.link_runs`) ---------------------
RUN_LINK = 0
RUN_COUNT = 1
RUN_K1 = 2
RUN_K2 = 3
RUN_EDGE = 4
RUN_GENERAL = 5
RUN_WIDTH = 6

# -- columns of a row of ``mo_runs`` (:func:`rivercal.engine.plan.momentum_runs`) -----------------
MO_LINK = 0
MO_COUNT = 1
MO_K1 = 2
MO_WIDTH = 3

#: Values per elimination step and lane of the solver schedule (:func:`rivercal.engine.plan.solver_schedule`).
SCHED_WIDTH = 8
#: Lanes per step of the solver schedule: eliminations whose dependency chains the processor overlaps.
SCHED_LANES = 4

#: Values per table cell in ``tab_flow`` (:func:`rivercal.engine.geometry.flow_records`): af, its increment,
#: pf, its increment, r43, its increment, 2 unused (one 64-byte cache line).
FLOW_WIDTH = 8
