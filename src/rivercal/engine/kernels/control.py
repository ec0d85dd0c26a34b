"""Controllers: the crest of a controlled weir for the coming step, once per (outer) time step.

:func:`control_step` runs at the start of step n → n+1, before the hydraulics, from the state at n (levels
``z``, fluxes ``q``): each controller sets the crest (m AD) that the weir keeps for the whole step — also
when the step is divided into sub-steps. The arrays are those of :class:`rivercal.engine.controllers.ControlArrays`
(``cx``); its ``state`` rows are the controllers' part of the engine state, so a run split in two equals the
whole.

Per controller, with the target T of its kind (PID, interval, time table, relation), the crest is

    crest_{n+1} = min(max(T, crest_n - v Δt, lo), crest_n + v Δt, hi)   (v: its speed limit, m/s)

The PID is the position form on e = setpoint - measured,
T = bias + kp e + ki I + kd (e - e_prev)/Δt with I += e Δt (rectangle rule), and the integral is held
(conditional integration) in a step where the crest is limited and e would drive it further into the limit.
"""

from __future__ import annotations

from rivercal.engine.kernels._jit import kernel

__all__ = [
    "CTL_INTERVAL",
    "CTL_PID",
    "CTL_RELATION",
    "CTL_TIME",
    "N_PAR",
    "N_STATE",
    "control_step",
    "record_controls",
    "start_controls",
]

# controller kinds (ControlArrays.kind)
CTL_PID = 0
CTL_INTERVAL = 1
CTL_TIME = 2
CTL_RELATION = 3

# columns of ControlArrays.par: setpoint (m AD or m³/s), gains (m/m, 1/s, s), bias (m AD), crest limits (m AD),
# speed limit (m/s; inf: none), dead band (m), step (m), interval (s)
P_SETPOINT = 0
P_KP = 1
P_KI = 2
P_KD = 3
P_BIAS = 4
P_LO = 5
P_HI = 6
P_SPEED = 7
P_BAND = 8
P_STEP = 9
P_INTERVAL = 10
N_PAR = 11

# columns of ControlArrays.state: integral (m·s), last error (m), crest (m AD), time since the last action (s),
# interval controller's target crest (m AD), started (0/1)
S_INTEGRAL = 0
S_ERROR = 1
S_CREST = 2
S_TIMER = 3
S_TARGET = 4
S_STARTED = 5
N_STATE = 6

OBS_LEVEL = 0  # == codes.OBS_LEVEL (checked by the tests)


@kernel
def _measured(cx, c, z, q):
    if cx.m_type[c] == OBS_LEVEL:
        w = cx.m_w[c]
        return w * z[cx.m_i1[c]] + (1.0 - w) * z[cx.m_i2[c]]
    return cx.m_w[c] * q[cx.m_i1[c]]


@kernel
def _relation(cx, c, x):
    lo, hi = cx.rel_ptr[c], cx.rel_ptr[c + 1]
    if x <= cx.rel_x[lo]:
        return cx.rel_y[lo]
    for k in range(lo + 1, hi):
        if x <= cx.rel_x[k]:
            s = (x - cx.rel_x[k - 1]) / (cx.rel_x[k] - cx.rel_x[k - 1])
            return cx.rel_y[k - 1] + s * (cx.rel_y[k] - cx.rel_y[k - 1])
    return cx.rel_y[hi - 1]


@kernel
def start_controls(cx, crest):
    """Before a run: every controlled weir takes its controller's crest (m AD).

    A controller that has not run yet (a cold start) starts from the weir's crest, without an integral.
    """
    for c in range(cx.kind.size):
        st = cx.state[c]
        if st[S_STARTED] == 0.0:
            st[S_INTEGRAL] = 0.0
            st[S_ERROR] = 0.0
            st[S_TIMER] = 0.0
            st[S_CREST] = crest[cx.weir[c]]
            st[S_TARGET] = crest[cx.weir[c]]
        crest[cx.weir[c]] = st[S_CREST]


@kernel
def control_step(cx, n, dt, z, q, crest):
    """Set the crests (m AD) of the controlled weirs for step ``n`` and update the controllers' state.

    From the levels ``z`` (m AD) and fluxes ``q`` (m³/s) at the start of the step of ``dt`` seconds.
    """
    for c in range(cx.kind.size):
        par = cx.par[c]
        st = cx.state[c]
        kind = cx.kind[c]
        col = cx.tcol[c]
        prev = st[S_CREST]
        e = 0.0
        integral = 0.0
        if kind == CTL_TIME:
            target = cx.sched[n, col]
        elif kind == CTL_RELATION:
            target = _relation(cx, c, _measured(cx, c, z, q))
        else:
            sp = par[P_SETPOINT] if col < 0 else cx.sched[n, col]
            e = sp - _measured(cx, c, z, q)
            if kind == CTL_PID:
                if st[S_STARTED] == 0.0:
                    st[S_ERROR] = e  # no derivative kick on the first step
                integral = st[S_INTEGRAL] + e * dt
                target = (par[P_BIAS] + par[P_KP] * e + par[P_KI] * integral
                          + par[P_KD] * (e - st[S_ERROR]) / dt)
            else:  # interval
                st[S_TIMER] += dt
                target = st[S_TARGET]
                if st[S_TIMER] >= par[P_INTERVAL] * (1.0 - 1e-12):
                    st[S_TIMER] = 0.0
                    half = 0.5 * par[P_BAND]
                    if e < -half:  # measured above the band
                        target -= par[P_STEP]
                    elif e > half:
                        target += par[P_STEP]
                    target = min(max(target, par[P_LO]), par[P_HI])
                    st[S_TARGET] = target
        lo = max(par[P_LO], prev - par[P_SPEED] * dt)
        hi = min(par[P_HI], prev + par[P_SPEED] * dt)
        out = min(max(target, lo), hi)
        if kind == CTL_PID:
            # conditional integration: hold the integral while limited and the error pushes further into the limit
            if out == target or (target - out) * (par[P_KI] * e) <= 0.0:
                st[S_INTEGRAL] = integral
            st[S_ERROR] = e
        st[S_CREST] = out
        st[S_STARTED] = 1.0
        crest[cx.weir[c]] = out


@kernel
def record_controls(cx, row):
    """Write the controlled crests (m AD) into output row ``row`` of ``cx.out``."""
    if row < cx.out.shape[0]:
        for c in range(cx.kind.size):
            cx.out[row, c] = cx.state[c, S_CREST]
