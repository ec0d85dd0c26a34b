"""The time loop of the staggered Delft scheme: one compiled call per simulated window.

Per step n → n+1 (reference note §A; Stelling & Duinmeijer 2003), each phase in its own module:

1. :mod:`~rivercal.engine.kernels.forcing` — boundary discharges and levels, laterals
   (:func:`~.forcing.apply_forcing`). Withdrawals (negative discharges of boundaries and laterals) are
   limited to half of the water present at their point per step; what they lack is counted.
2. :mod:`.momentum` — each channel link's momentum equation from the state at n, with Newton-linearised
   friction, as ``u = r - f (z2 - z1)`` (:func:`~.momentum.channel_coefficients`); pumps switch on the
   suction-side level (:func:`~.structures.switch_pumps`).
3. :mod:`.picard` — Picard iterations: the structures' laws (:mod:`~rivercal.engine.kernels.structures`: weir,
   culvert) linearised at the iterate, the level system assembled (:mod:`.assemble`) and solved (:mod:`.solver`).
4. :mod:`.fluxes` — the link fluxes of the solved levels, throttled where a point would drain dry, screened
   (:func:`~.fluxes.check_levels`), then committed to the volumes (:func:`~.fluxes.finish_step`), with the
   divergence checks.
5. :mod:`.record` — the station series at the output times.

**Step control.** ``engine.dt`` is the longest step; a step is divided into 2^level sub-steps (down to
2^``MAX_HALVINGS``, the way SOBEK halves a failing step) by two controls, the finer of whose levels is used:

- *stability*: when the flow is forecast to be too fast for the step — the explicit upwind depth would amplify
  level errors from step to step by more than ``AMP_RISE`` (:mod:`.stability`), which at Courant numbers above
  about 2 on a steep reach makes the solution alternate between two states or diverge — and when a solved
  (sub-)step fails the screen before it is committed (then it is computed again, shorter): a level more than
  ``DRY_TOLERANCE`` below its bed or NaN, a velocity above ``engine.max_velocity``. A level that flickers (turns up and
  down by more than ``FLICKER_DZ`` again and again within a few steps, :func:`.fluxes.finish_step`) makes the
  coming sub-steps finer. This level carries over to the next steps and falls by one after ``RELAX_STEPS``
  calm steps (twice as many each time a fall is undone at once);
- *accuracy*: the error estimate of a solved (sub-)step, the largest difference between a solved level and
  its extrapolation from the last (sub-)step's change (about half the curvature of the level's path times the
  step squared: the local error of the first-order time integration), must stay below ``ERR_REDO``, or the
  (sub-)step is computed again, halved; each step is sized for ``ERR_TARGET`` from the last one's estimate,
  and may become coarser by one level per step;
- *Courant* (with ``engine.courant``): the level at which no channel link's |u| Δt / Δx at the step's start
  exceeds the limit (:func:`_courant_level`), and a (sub-)step whose solved velocities exceed it
  ``COURANT_REDO`` times is computed again, finer.

A flicker that makes the coming sub-steps finer clears every point's flicker count: the swing dies out over
some of them, and only one that goes on at the finer step stops the run.

A divided step's sub-steps follow the discharges' course between the step's edges (:func:`.forcing.apply_forcing`);
a level boundary moves linearly to its level for the step's end. Where the Picard iterations of a (sub-)step could
not follow the channels' geometry (:func:`.picard.follow_geometry`), it is solved again with the geometry of its
start (:func:`_explicit`). When the
smallest sub-step still fails, the run stops with ``STATUS_DRY`` or ``STATUS_FLICKER`` and the point (or the
divergence's status and place). The control's state is part of the engine state, so that a run continued from a
state divides its steps as the whole run would. A run that never needs a division computes exactly what it
computed without the control.

Each phase is its own compiled function taking the network arrays (``net``) and the scratch arrays
(``work``, :func:`make_work`): LLVM optimises these small functions much better than one large loop
body. The per-point look-ups take explicit arrays (see :mod:`.lookup`).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from rivercal.engine.kernels._jit import entry, kernel
from rivercal.engine.kernels.codes import (
    AMP_FALL,
    AMP_RISE,
    BOUNDARY_LEVEL,
    COURANT_REDO,
    DRY_TOLERANCE,
    ERR_REDO,
    ERR_TARGET,
    LINK_CHANNEL,
    LINK_CULVERT,
    LINK_PUMP,
    LINK_WEIR,
    MAX_HALVINGS,
    N_STATS,
    RELAX_STEPS,
    STAT_ACC,
    STAT_ACC_NEXT,
    STAT_AMP,
    STAT_CALM,
    STAT_COURANT,
    STAT_EXPLICIT,
    STAT_FELL,
    STAT_LAST,
    STAT_LEVEL,
    STAT_MAX_LEVEL,
    STAT_REDONE,
    STAT_REFINED,
    STAT_RELAX,
    STAT_STEPS,
    STAT_SUBSTEPS,
    STATUS_DRY,
    STATUS_FLICKER,
    STATUS_OK,
)
from rivercal.engine.kernels.control import control_step, record_controls, start_controls
from rivercal.engine.kernels.fluxes import check_levels, finish_step, fluxes_within_volume, too_fast
from rivercal.engine.kernels.forcing import apply_forcing
from rivercal.engine.kernels.momentum import channel_coefficients
from rivercal.engine.kernels.picard import picard_iterations, picard_iterations_ext
from rivercal.engine.kernels.record import record
from rivercal.engine.kernels.stability import explicit_amplification
from rivercal.engine.kernels.structures import apply_settings, reset_settings, switch_pumps

__all__ = ["Work", "make_work", "run", "run_ext", "switch_dikes"]

#: A step in units of the smallest sub-step.
FULL = 1 << MAX_HALVINGS
#: :func:`_screen`'s verdict that the (sub-)step is to be computed again, shorter (not a run status).
SCREEN_REDO = -1

#: Scratch arrays of :func:`run` (kernels do not allocate; see :mod:`._jit`): matrix diagonal, right-hand
#: side, iterate (m AD), sources (m³/s), lateral inflow per unit length (m²/s), net inflow (m³/s), Dirichlet
#: flags and levels, off-diagonals and L multipliers per edge, link flux area (m²) and coefficients f (1/s)
#: and r (m/s), a second buffer of velocities (m/s) and fluxes (m³/s) that :func:`run` swaps with the
#: state's arrays every step, rating-boundary linearisation (m³/s, m²/s), the structure and pump links,
#: counters (``STAT_*`` of :mod:`.codes`), per point the piece of its volume curve last looked up
#: (:func:`.assemble.assemble`): low and high end and reference level (m AD), the volume there (m³) and the
#: storage area (m²); of each channel link (:func:`.momentum.channel_coefficients`) the
#: flow area (m²), wetted perimeter (m) and R^(4/3) (m^(4/3)) of its friction, and its friction value (unit of
#: its friction type); per discharge boundary its delivered discharge (m³/s), and per boundary then lateral the
#: withdrawal asked and not delivered in the (sub-)step (m³/s) and over the run (m³); the channel coefficients
#: (area, f, r) of the links that may become free overfalls (:mod:`.overfall`); per point the sums of the step
#: control's forecast (:mod:`.stability`, m²/s); per point the lowest level a step may leave (m AD); per point the
#: flicker count and the level's change since it last turned (m) (:func:`.fluxes.finish_step`); the points whose
#: level left the piece of its volume curve last looked up (:func:`.assemble.assemble`).
Work = namedtuple(
    "Work",
    ["diag", "rhs", "zk", "src", "qlat", "netq", "fixed", "fixed_val", "off", "lval", "area", "fco", "rco",
     "un", "qn", "rq0", "rslope", "struct_links", "pump_links", "stats", "zlo", "zhi", "p_z", "p_v", "p_w",
     "cam", "cper", "cr43", "lfric", "bq", "wreq", "wshort", "wreq_sum", "wshort_sum",
     "ovf", "anum", "aden", "floor", "flick", "swing", "outside"],
)


def make_work(net, sx=None) -> Work:
    """Allocate the scratch arrays of :func:`run` for network arrays ``net`` (``sx``: the structure arrays)."""
    n_h = net.hp_bed.size
    n_l = net.lk_k1.size
    n_b = net.b_hp.size
    return Work(
        diag=np.empty(n_h), rhs=np.empty(n_h), zk=np.empty(n_h), src=np.zeros(n_h), qlat=np.zeros(n_h),
        netq=np.empty(n_h),
        fixed=np.zeros(n_h, dtype=np.bool_), fixed_val=np.zeros(n_h), off=np.zeros(net.sv_nedge),
        lval=np.zeros(net.sv_nedge), area=np.zeros(n_l), fco=np.zeros(n_l), rco=np.zeros(n_l),
        un=np.zeros(n_l), qn=np.zeros(n_l),
        rq0=np.zeros(n_b), rslope=np.zeros(n_b),
        struct_links=np.setdiff1d(np.flatnonzero((net.lk_type == LINK_WEIR) | (net.lk_type == LINK_CULVERT)),
                                   sx.links if sx is not None else []).astype(np.int64),
        pump_links=np.flatnonzero(net.lk_type == LINK_PUMP).astype(np.int64),
        stats=np.zeros(N_STATS, dtype=np.int64),
        zlo=np.full(n_h, np.inf), zhi=np.full(n_h, -np.inf), p_z=np.zeros(n_h), p_v=np.zeros(n_h), p_w=np.zeros(n_h),
        cam=np.ones(n_l), cper=np.ones(n_l), cr43=np.ones(n_l),
        lfric=np.ones(n_l),
        bq=np.zeros(n_b), wreq=np.zeros(n_b + net.lat_hp.size), wshort=np.zeros(n_b + net.lat_hp.size),
        wreq_sum=np.zeros(n_b + net.lat_hp.size), wshort_sum=np.zeros(n_b + net.lat_hp.size),
        ovf=np.zeros((3, net.dl_link.size)), anum=np.zeros(n_h), aden=np.zeros(n_h),
        floor=_floor(net), flick=np.zeros(n_h, dtype=np.int32), swing=np.zeros(n_h),
        outside=np.zeros(n_h, dtype=np.int64),
    )


def _floor(net) -> np.ndarray:
    """The lowest level a (sub-)step may leave at each point (:func:`.fluxes.check_levels`), m AD.

    Its bed less ``DRY_TOLERANCE``; none (-inf) where a level boundary imposes the level.
    """
    floor = net.hp_bed - DRY_TOLERANCE
    floor[net.b_hp[net.b_type == BOUNDARY_LEVEL]] = -np.inf
    return floor


@entry
def run(net, work, crest, fric, z, dz, vol, u, q, pump_on, forcing, edges, dt, theta, max_iter, tol, min_depth, vmax,
        courant, out_every, obs_out, z_out, q_out, balance):
    """Advance the state over ``forcing.shape[0]`` steps of ``dt`` seconds.

    Parameters
    ----------
    net
        :class:`~rivercal.engine.compile.NetArrays`.
    work
        :class:`Work` arrays (scratch, allocated once by the caller).
    crest, fric
        Run-time parameters: weir crest levels (m AD) and friction values per branch.
    z, dz, vol, u, q, pump_on
        State, updated in place: levels (m AD), their change over the last step (m) and volumes
        (m³) at h-points, velocities (m/s) and fluxes (m³/s) at links, pump switches (0/1).
    forcing
        Per step and forcing column: the step-mean discharge (m³/s) or the level at the end of
        the step (m AD).
    edges
        Per step (two rows: its start and end) and forcing column: the discharge (m³/s) that the sub-steps of a
        divided step follow (:func:`.forcing.apply_forcing`); without rows, they take the step's mean.
    dt, theta, max_iter, tol, min_depth, vmax, courant
        Step (s), implicitness, Picard iterations, level tolerance (m), minimum flow depth (m),
        divergence velocity (m/s), largest flow Courant number of a (sub-)step (0: none).
    out_every, obs_out, z_out, q_out
        Output every ``out_every`` steps: observables into ``obs_out`` (row 0 = initial state) and,
        when they have rows, full levels and fluxes into ``z_out`` and ``q_out``.
    balance
        Accumulates the volume (m³) that entered through each boundary (first entries) and through
        all laterals (last entry).

    Returns
    -------
    tuple of int
        (status, step, index): ``STATUS_OK``, or ``STATUS_LEVEL`` or ``STATUS_DRY`` with the h-point, or
        ``STATUS_VELOCITY`` with the link at which the run failed.
    """
    record(net, 0, z, q, obs_out, z_out, q_out)
    # velocities and fluxes at time n (u0, q0) and n+1 (u1, q1): the arrays swap roles after each step
    u0, q0, u1, q1 = u, q, work.un, work.qn
    _start(net, work, fric)
    for n in range(forcing.shape[0]):
        work.stats[STAT_STEPS] += 1
        status, index, swap = _step(net, None, None, work, n, crest, z, dz, vol, u0, q0, u1, q1, pump_on, forcing,
                                    edges, dt, theta, max_iter, tol, min_depth, vmax, courant, balance)
        if swap:
            u0, q0, u1, q1 = u1, q1, u0, q0
        if status != STATUS_OK:
            _keep(u0, q0, u, q)
            return status, n, index
        if (n + 1) % out_every == 0:
            record(net, (n + 1) // out_every, z, q0, obs_out, z_out, q_out)
    _keep(u0, q0, u, q)
    return STATUS_OK, forcing.shape[0], -1


@entry
def run_ext(net, sx, cx, dk, work, crest, fric, z, dz, vol, u, q, pump_on, forcing, edges, dt, theta, max_iter, tol,
            min_depth, vmax, courant, out_every, obs_out, z_out, q_out, balance):
    """:func:`run` for a network with structures of D-HYDRO's kinds or structure settings that follow a series.

    A separate kernel, so that the time loop of a network without them stays as lean as before (its phases
    are inlined and receive no more arrays; measured: the same time as before these structures existed).
    Advance the state over ``forcing.shape[0]`` steps of ``dt`` seconds.

    Parameters
    ----------
    net
        :class:`~rivercal.engine.compile.NetArrays`.
    sx
        :class:`~rivercal.engine.compile.StructureArrays` (orifices, universal weirs, culvert extras, settings
        series).
    cx
        :class:`~rivercal.engine.controllers.ControlArrays` (controllers, their run's quantities, output and
        state, updated in place), or ``None`` without controllers. A controller sets its weir's crest once per
        step, before the hydraulics (:func:`.control.control_step`).
    dk
        :class:`~rivercal.engine.compile.DikeArrays` (summer dikes whose storage changes curve; empty arrays
        without them); with them ``net.sc_prof`` is the run's own copy, whose tables :func:`switch_dikes` changes.
    work
        :class:`Work` arrays (scratch, allocated once by the caller).
    crest, fric
        Run-time parameters: weir crest levels (m AD; a weir whose crest follows a series or a controller takes
        its value each step) and friction values per friction slot (branches, then friction groups).
    z, dz, vol, u, q, pump_on
        State, updated in place: levels (m AD), their change over the last step (m) and volumes
        (m³) at h-points, velocities (m/s) and fluxes (m³/s) at links, pump switches (0/1).
    forcing
        Per step and forcing column: the step-mean discharge (m³/s) or the level at the end of
        the step (m AD).
    edges
        Per step (two rows: its start and end) and forcing column: the discharge (m³/s) that the sub-steps of a
        divided step follow (:func:`.forcing.apply_forcing`); without rows, they take the step's mean.
    dt, theta, max_iter, tol, min_depth, vmax, courant
        Step (s), implicitness, Picard iterations, level tolerance (m), minimum flow depth (m),
        divergence velocity (m/s), largest flow Courant number of a (sub-)step (0: none).
    out_every, obs_out, z_out, q_out
        Output every ``out_every`` steps: observables into ``obs_out`` (row 0 = initial state) and,
        when they have rows, full levels and fluxes into ``z_out`` and ``q_out``.
    balance
        Accumulates the volume (m³) that entered through each boundary (first entries) and through
        all laterals (last entry).

    Returns
    -------
    tuple of int
        (status, step, index): ``STATUS_OK``, or ``STATUS_LEVEL`` or ``STATUS_DRY`` with the h-point, or
        ``STATUS_VELOCITY`` with the link at which the run failed.
    """
    record(net, 0, z, q, obs_out, z_out, q_out)
    if cx is not None:
        start_controls(cx, crest)
        record_controls(cx, 0)
    # velocities and fluxes at time n (u0, q0) and n+1 (u1, q1): the arrays swap roles after each step
    u0, q0, u1, q1 = u, q, work.un, work.qn
    _start(net, work, fric)
    reset_settings(net, sx)
    scheduled = False  # any structure setting that follows a series (most cases have none)
    for k in range(sx.set_col.size):
        scheduled |= sx.set_col[k] >= 0
    for n in range(forcing.shape[0]):
        work.stats[STAT_STEPS] += 1
        if scheduled:
            apply_settings(net, sx, n, forcing, crest)
        if cx is not None:
            control_step(cx, n, dt, z, q0, crest)
        status, index, swap = _step(net, sx, dk, work, n, crest, z, dz, vol, u0, q0, u1, q1, pump_on, forcing,
                                    edges, dt, theta, max_iter, tol, min_depth, vmax, courant, balance)
        if swap:
            u0, q0, u1, q1 = u1, q1, u0, q0
        if status != STATUS_OK:
            _keep(u0, q0, u, q)
            return status, n, index
        if (n + 1) % out_every == 0:
            record(net, (n + 1) // out_every, z, q0, obs_out, z_out, q_out)
            if cx is not None:
                record_controls(cx, (n + 1) // out_every)
    _keep(u0, q0, u, q)
    return STATUS_OK, forcing.shape[0], -1


@kernel(inline=True)
def _step(net, sx, dk, work, n, crest, z, dz, vol, u0, q0, u1, q1, pump_on, forcing, edges, dt, theta, max_iter, tol,
          min_depth, vmax, courant, balance):
    """Advance the state over step ``n`` of ``dt`` s, in sub-steps where the step control divides it.

    The arguments are those of :func:`run_ext`, with ``sx`` and ``dk`` ``None`` for :func:`run`'s networks (the
    branches on them are pruned when compiling); ``u0``, ``q0`` hold the velocities (m/s) and fluxes (m³/s) at the
    step's start and ``u1``, ``q1`` receive the next ones, swapping roles after each sub-step. Returns (status, index,
    swapped): the status and point or link of :func:`run`, and whether the last committed values ended in
    ``u1``, ``q1`` after an odd number of sub-steps (the caller swaps its arrays then).
    """
    n_b = net.b_hp.size
    stats = work.stats
    swapped = False
    done = 0
    taken = 0
    status, index = STATUS_OK, -1
    _accuracy_level(stats)
    stats[STAT_COURANT] = _courant_level(net, u0, dt, courant) if courant > 0.0 else 0
    while done < FULL and status == STATUS_OK:  # one way in and one way out: a smaller compiled loop
        level = _level(stats)
        span = FULL >> level
        h = dt * span / FULL
        last = stats[STAT_LAST]  # a sub-step shorter than the last extrapolates the last change over its length
        ahead = 1.0 / (1 << (level - last)) if level > last else 1.0
        lateral = apply_forcing(net, work, n, forcing, edges, h, vol, z, span / (FULL - done), done / FULL,
                                (done + span) / FULL)
        fastest = channel_coefficients(net, work, z, z, theta, u0, q0, h, min_depth, False)  # the geometry of time n
        if _too_fast(net, work, z, u0, h, theta, min_depth, fastest, level):
            continue
        switched = switch_pumps(net, work, z, pump_on)
        if sx is None:
            followed = picard_iterations(net, work, z, dz, vol, u0, q0, pump_on, crest, theta, h, max_iter, tol,
                                         min_depth, True, ahead)
        elif sx.links.size > 0:
            followed = picard_iterations_ext(net, sx, work, z, dz, vol, u0, q0, pump_on, crest, theta, h, max_iter,
                                             tol, min_depth, True, ahead)
        else:
            followed = picard_iterations(net, work, z, dz, vol, u0, q0, pump_on, crest, theta, h, max_iter, tol,
                                         min_depth, True, ahead)
        if not followed:
            _explicit(net, sx, work, z, dz, vol, u0, q0, pump_on, crest, theta, h, max_iter, tol, min_depth, ahead)
        fluxes_within_volume(net, work, vol, theta, h, tol, u0, u1, q1)
        status, index = _screen(net, work, z, dz, u1, vmax, level, done == 0, courant * FULL / (span * dt))
        if status == STATUS_OK:
            balance[n_b] += h * lateral
            checked = vmax if level >= MAX_HALVINGS else math.inf  # the screen checked the velocities
            # a level turning because a pump switched is its control's cycle, not the scheme's flicker
            status, index = finish_step(net, work, h, checked, z, dz, vol, u1, q1, balance, switched == 0)
            if dk is not None and dk.sc.size > 0:
                switch_dikes(dk, net.sc_prof, work, z)
            u0, q0, u1, q1 = u1, q1, u0, q0
            swapped = not swapped
            done += span
            taken += 1
            if done == FULL:  # whole steps: relaxed per sub-step, a steep reach's steady flow drifted 4 cm
                _relax(stats, done)
            if status == STATUS_FLICKER and level < MAX_HALVINGS:
                _rise(stats, level)  # the coming (sub-)steps shorter; this one stands
                work.flick[:] = 0  # what the longer sub-steps counted does not count against the shorter ones
                status, index = STATUS_OK, -1
        elif status == SCREEN_REDO:
            stats[STAT_REDONE] += 1
            status = STATUS_OK
    if taken > 1:
        stats[STAT_REFINED] += 1
        stats[STAT_SUBSTEPS] += taken
        stats[STAT_MAX_LEVEL] = max(stats[STAT_MAX_LEVEL], _level(stats))
    return status, index, swapped


@kernel
def switch_dikes(dk, sc_prof, work, z):
    """After a committed (sub-)step: the storage curve of each summer dike (:class:`~.compile.DikeArrays`), by level.

    A dike on its rising curve whose point's level ``z`` (m AD) has reached its full level drains by its falling
    curve from then on, and one on its falling curve whose level has fallen to its base fills by its rising curve
    again (SOBEK 3's hysteresis of the summer dike's total area). ``sc_prof`` is the run's own table of each
    storage contribution. Both curves hold the same volume at those levels, so the point keeps its volume and its
    level; the piece of its volume curve looked up last (``work.zlo``, ``work.zhi``) no longer holds and is
    dropped.
    """
    for k in range(dk.sc.size):
        c = dk.sc[k]
        i = dk.hp[k]
        zi = z[i]
        if sc_prof[c] == dk.rise[k]:
            if zi >= dk.full[k]:
                sc_prof[c] = dk.alt[k]
                work.zlo[i] = math.inf
                work.zhi[i] = -math.inf
        elif zi <= dk.base[k]:
            sc_prof[c] = dk.rise[k]
            work.zlo[i] = math.inf
            work.zhi[i] = -math.inf


@kernel
def _explicit(net, sx, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth, ahead):
    """Solve a (sub-)step again with the channels' geometry of its start, where that of the iterate did not converge.

    The arguments are those of :func:`.picard.picard_iterations` (``sx`` None: a network without D-HYDRO's
    structures; ``ahead`` the sub-step's length over the last one's, at most 1); counted in ``STAT_EXPLICIT``.
    """
    work.stats[STAT_EXPLICIT] += 1
    channel_coefficients(net, work, z, z, theta, u, q, dt, min_depth, False)
    switch_pumps(net, work, z, pump_on)
    if sx is None:
        picard_iterations(net, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth, False,
                          ahead)
    elif sx.links.size > 0:
        picard_iterations_ext(net, sx, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth,
                              False, ahead)
    else:
        picard_iterations(net, work, z, dz, vol, u, q, pump_on, crest, theta, dt, max_iter, tol, min_depth, False,
                          ahead)


@kernel
def _level(stats):
    """The sub-step level of the coming (sub-)step: the finest of the stability's, the accuracy's and the Courant's."""
    return max(stats[STAT_LEVEL], stats[STAT_ACC], stats[STAT_COURANT])


@kernel
def _crossed(net, u, fastest):
    """Whether some channel link's |u| / Δx (velocities ``u``, m/s) exceeds ``fastest`` (1/s)."""
    crossed = False
    lk_type, ilen = net.lk_type, net.lk_ilen
    for link in range(u.size):
        crossed |= (math.fabs(u[link]) * ilen[link] > fastest) & (lk_type[link] == LINK_CHANNEL)
    return crossed


@kernel
def _courant_level(net, u, dt, courant):
    """The sub-step level at which no channel link's flow Courant number |u| Δt / Δx exceeds ``courant``.

    From the velocities ``u`` (m/s) at the step's start (the state alone: a run continued from a state divides as
    the whole run); a step of ``dt`` s is divided into 2^level sub-steps, at most 2^``MAX_HALVINGS``.
    """
    fastest = 0.0
    lk_type, ilen = net.lk_type, net.lk_ilen
    for link in range(u.size):
        fastest = max(fastest, math.fabs(u[link]) * ilen[link] if lk_type[link] == LINK_CHANNEL else 0.0)
    level = 0
    h = dt
    while level < MAX_HALVINGS and fastest * h > courant:
        level += 1
        h *= 0.5
    return level


@kernel
def _accuracy_level(stats):
    """At a step's start: the accuracy's sub-step level, as the last step forecast it (falling by one at most)."""
    stats[STAT_ACC] = max(stats[STAT_ACC_NEXT], stats[STAT_ACC] - 1, 0)
    stats[STAT_ACC_NEXT] = 0


@kernel
def _start(net, work, fric):
    """Reset the per-run scratch arrays and take the run's friction values per link; arm the step control."""
    work.src[:] = 0.0
    work.qlat[:] = 0.0
    work.fixed[:] = False
    for link in range(work.lfric.size):
        work.lfric[link] = fric[net.lk_fric[link]]
    if work.stats[STAT_RELAX] == 0:
        work.stats[STAT_RELAX] = RELAX_STEPS


@kernel
def _too_fast(net, work, z, u, dt, theta, min_depth, fastest, level):
    """Whether a (sub-)step of ``dt`` s is too long for the explicit upwind depth; if so, raise the sub-step level.

    The forecast of the step control (:mod:`.stability`), from the state at the step's start: the
    amplification is computed only when some link is crossed in less than the step (``fastest``, the largest
    |u| / Δx of the wet channel links, 1/s, from :func:`.momentum.channel_coefficients`), and kept (in millionths,
    ``STAT_AMP``) for the decision to let the level fall.
    """
    stats = work.stats
    amp = 0.0
    if fastest * dt > 1.0:
        amp = explicit_amplification(net, work, z, u, dt, theta, min_depth)
    stats[STAT_AMP] = int(min(amp, 1.0e6) * 1.0e6)
    if amp <= AMP_RISE or level >= MAX_HALVINGS:
        return False
    _rise(stats, level)
    return True


@kernel
def _rise(stats, level):
    """Make the stability's sub-step level one finer than ``level``, the current one.

    A fall that is undone before its calm period ends doubles that period.
    """
    if stats[STAT_FELL] == 1 and stats[STAT_CALM] < stats[STAT_RELAX]:
        stats[STAT_RELAX] = min(2 * stats[STAT_RELAX], RELAX_STEPS << 8)  # the fall was too early
    stats[STAT_LEVEL] = level + 1
    stats[STAT_MAX_LEVEL] = max(stats[STAT_MAX_LEVEL], level + 1)
    stats[STAT_CALM] = 0
    stats[STAT_FELL] = 0


@kernel
def _screen(net, work, z, dz, un, vmax, level, first, fastest):
    """The step control's verdict on a solved (sub-)step at sub-step ``level``, before it is committed.

    ``fastest`` (1/s) is the largest |u| / Δx the Courant limit allows in the (sub-)step (0 without one): a
    (sub-)step whose solved velocities ``un`` cross a channel link more than ``COURANT_REDO`` times faster is computed
    again at the next finer level (the limit is taken from the velocities at each step's start, and a cold start
    from rest has none).

    ``first`` marks the first sub-step of a step. The forcing's course may bend there (level boundaries head
    for the next step's level, controllers act, and a discharge series bends at its own times), so a divided
    step's level may bend there whatever the sub-step's length: its accuracy estimate is left out, and the
    sub-steps after it size the coming steps. An undivided step's estimate, which spans the change of the
    forcing, counts.

    Returns (``STATUS_OK``, -1) to commit, (``SCREEN_REDO``, -1) after making the sub-step finer (it is computed
    again, shorter), or (``STATUS_DRY``, point) when the smallest sub-step fails. A (sub-)step is computed again,
    shorter, when a level falls more than ``DRY_TOLERANCE`` below its bed or is NaN (:func:`.fluxes.check_levels`);
    when a velocity ``un`` (m/s) exceeds ``vmax`` (a divergence, which :func:`.fluxes.finish_step` reports at the
    smallest sub-step); and when a level ``z`` (m AD) moves more than
    ``ERR_REDO`` from its extrapolation (accuracy, :func:`.fluxes.check_levels`). A committed (sub-)step sets the
    accuracy's forecast for the next step: the sub-step level at which that error, growing with the step squared,
    stays within ``ERR_TARGET``.
    """
    stats = work.stats
    last = stats[STAT_LAST]
    shorter = (1 << (level - last)) if level >= last else 1.0 / (1 << (last - level))
    dry, error = check_levels(net, work, z, dz, shorter, 0.25 * ERR_TARGET)
    if dry >= 0:
        if level >= MAX_HALVINGS:
            return STATUS_DRY, dry
        _rise(stats, level)
        return SCREEN_REDO, -1
    if level >= MAX_HALVINGS:
        stats[STAT_LAST] = level
        return STATUS_OK, -1
    if too_fast(un, vmax):
        _rise(stats, level)
        return SCREEN_REDO, -1
    if fastest > 0.0 and _crossed(net, un, COURANT_REDO * fastest):
        stats[STAT_COURANT] = level + 1
        stats[STAT_MAX_LEVEL] = max(stats[STAT_MAX_LEVEL], level + 1)
        return SCREEN_REDO, -1
    if first and level > 0:
        stats[STAT_LAST] = level
        return STATUS_OK, -1
    if error > ERR_REDO:
        stats[STAT_ACC] = level + 1
        stats[STAT_MAX_LEVEL] = max(stats[STAT_MAX_LEVEL], level + 1)
        return SCREEN_REDO, -1
    wanted = level  # the error grows with the step squared: a level coarser quadruples it
    scaled = error
    if scaled > ERR_TARGET:
        while scaled > ERR_TARGET and wanted < MAX_HALVINGS:
            wanted += 1
            scaled *= 0.25
    else:
        while wanted > 0 and 4.0 * scaled <= ERR_TARGET:
            wanted -= 1
            scaled *= 4.0
    stats[STAT_ACC_NEXT] = max(stats[STAT_ACC_NEXT], wanted)
    stats[STAT_LAST] = level
    return STATUS_OK, -1


@kernel
def _relax(stats, done):
    """After a committed step: let the stability's sub-step level fall by one after enough calm steps.

    ``done`` is the part of the step done (in units of the smallest sub-step); the level falls only where the
    coarser sub-step fits the rest of the step from there.
    """
    level = stats[STAT_LEVEL]
    if level == 0:
        return
    stats[STAT_CALM] += 1
    if stats[STAT_CALM] >= stats[STAT_RELAX] and stats[STAT_AMP] < AMP_FALL * 1.0e6:
        coarser = max(level - 1, stats[STAT_ACC])
        if done % (FULL >> coarser) == 0:
            stats[STAT_LEVEL] = level - 1
            stats[STAT_CALM] = 0
            stats[STAT_FELL] = 1


@kernel
def _keep(u_last, q_last, u, q):
    """Copy the last velocities and fluxes into the state arrays ``u``, ``q`` unless they are already there."""
    if u_last.ctypes.data != u.ctypes.data:
        for link in range(u.size):
            u[link] = u_last[link]
            q[link] = q_last[link]
