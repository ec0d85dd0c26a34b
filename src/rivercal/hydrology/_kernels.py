"""Numba kernels of the WALRUS-type rainfall-runoff model (arrays and scalars only).

The equations, symbols and units are documented in :mod:`rivercal.hydrology.runoff`. The kernels
assume valid input (finite forcing, parameters inside their bounds); :func:`~rivercal.hydrology.runoff.simulate`
validates at the boundary.

Parameter vector ``par`` (all float64), in this order::

    0 c_w    wetness index parameter                     mm
    1 c_v    vadose zone relaxation time                  h
    2 c_g    groundwater reservoir constant               mm h
    3 c_q    quickflow reservoir constant                 h
    4 c_s    bankfull discharge                           mm/h
    5 c_d    channel depth                                mm
    6 a_s    surface water area fraction                  -
    7 x_s    stage-discharge exponent                     -
    8 b      Clapp-Hornberger pore-size exponent           -
    9 psi_ae air-entry pressure head                      mm
   10 theta_s porosity                                    -
   11 zeta1  evapotranspiration reduction steepness        1/mm
   12 zeta2  storage deficit of half reduction            mm
   13 max_change  largest change of h_s or d_v per substep  mm
   14 min_substep smallest substep                        h

State vector ``state`` (float64[4]): ``d_v, d_g, h_q, h_s`` (mm), updated in place.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rivercal._kernel_cache import install

__all__ = ["equilibrium_deficit", "et_reduction", "run_walrus", "wetness"]

install()  # the compiled kernels are kept per user and version of these sources (rivercal._kernel_cache)

NPAR = 15


@njit(cache=True)
def wetness(d_v: float, c_w: float) -> float:
    """Wetness index W (-) for storage deficit ``d_v`` (mm): 1 when wet, 0 beyond ``c_w``."""
    x = min(max(d_v, 0.0), c_w)
    return 0.5 * math.cos(x * math.pi / c_w) + 0.5


@njit(cache=True)
def et_reduction(d_v: float, zeta1: float, zeta2: float) -> float:
    """Evapotranspiration reduction factor beta (-) for storage deficit ``d_v`` (mm)."""
    z = zeta1 * (d_v - zeta2)
    if z > 700.0:
        return 0.0
    e = math.exp(z)
    return 0.5 + 0.5 * (1.0 - e) / (1.0 + e)


@njit(cache=True)
def equilibrium_deficit(d_g: float, b: float, psi_ae: float, theta_s: float) -> float:
    """Storage deficit (mm) of a vadose zone in hydrostatic equilibrium with groundwater depth ``d_g`` (mm)."""
    if d_g <= 0.0:
        return d_g
    if d_g <= psi_ae:
        return 0.0
    inv_b = 1.0 / b
    return theta_s * (d_g - d_g ** (1.0 - inv_b) * psi_ae**inv_b / (1.0 - inv_b) - psi_ae / (1.0 - b))


@njit(cache=True)
def run_walrus(
    precip: np.ndarray,
    etpot: np.ndarray,
    dt: float,
    par: np.ndarray,
    state: np.ndarray,
    q_out: np.ndarray,
    et_out: np.ndarray,
    fqs_out: np.ndarray,
    fgs_out: np.ndarray,
    states_out: np.ndarray,
    w_out: np.ndarray,
    nsub_out: np.ndarray,
) -> None:
    """Integrate the model over ``len(precip)`` forcing steps of ``dt`` hours.

    Parameters
    ----------
    precip, etpot
        Precipitation and potential evapotranspiration rates (mm/h), constant within a step.
    dt
        Forcing step (h).
    par
        Parameter vector (see the module docstring).
    state
        ``d_v, d_g, h_q, h_s`` (mm) at the start; holds the final state on return.
    q_out, et_out, fqs_out, fgs_out
        Per step: mean discharge, actual evapotranspiration, quickflow and groundwater drainage
        to the surface water, all in mm/h over the whole catchment.
    states_out
        ``(n, 4)``: ``d_v, d_g, h_q, h_s`` (mm) at the end of each step.
    w_out
        Wetness index (-) at the end of each step.
    nsub_out
        Number of substeps taken in each step.
    """
    c_w = par[0]
    c_v = par[1]
    c_g = par[2]
    c_q = par[3]
    c_s = par[4]
    c_d = par[5]
    a_s = par[6]
    x_s = par[7]
    b = par[8]
    psi_ae = par[9]
    theta_s = par[10]
    zeta1 = par[11]
    zeta2 = par[12]
    max_change = par[13]
    min_sub = par[14]
    a_l = 1.0 - a_s
    d_v = state[0]
    d_g = state[1]
    h_q = state[2]
    h_s = state[3]
    for i in range(precip.shape[0]):
        p = precip[i]
        e = etpot[i]
        vol_q = 0.0
        vol_et = 0.0
        vol_fqs = 0.0
        vol_fgs = 0.0
        t = 0.0
        nsub = 0
        while t < dt:
            # fluxes at the current state (land fluxes per unit land area, q per unit catchment area)
            w = wetness(d_v, c_w)
            etv = et_reduction(d_v, zeta1, zeta2) * e
            depth = c_d - d_g
            fgs = (depth - h_s) * max(depth, h_s) / c_g
            hs_pos = max(h_s, 0.0)
            q = c_s * (hs_pos / c_d) ** x_s
            ets = e if h_s > 0.0 else 0.0
            d_veq = equilibrium_deficit(d_g, b, psi_ae, theta_s)
            # substep: explicit stability (stiffness of h_s and d_g) and a bound on the change of h_s, d_v
            h = dt - t
            k_s = c_s * x_s / c_d * (hs_pos / c_d) ** (x_s - 1.0) / a_s if hs_pos > 0.0 else 0.0
            k_s += a_l / a_s * max(depth, h_s) / c_g
            k_g = theta_s / c_v
            k = max(k_s, k_g)
            if h * k > 0.5:
                h = 0.5 / k
            rate_s = abs(p - ets + a_l / a_s * (fgs + h_q / c_q) - q / a_s)
            rate_v = abs(-(1.0 - w) * p + etv + fgs)
            if rate_s * h > max_change:
                h = max_change / rate_s
            if rate_v * h > max_change:
                h = max_change / rate_v
            h = max(h, min_sub)
            if t + h > dt or dt - (t + h) < 1e-9 * dt:
                h = dt - t
            # volumes over the substep (mm over the area each applies to)
            v_pq = w * p * h
            v_pv = (1.0 - w) * p * h
            v_etv = etv * h
            v_fgs = fgs * h
            decay = math.exp(-h / c_q)
            h_q_new = h_q * decay + w * p * c_q * (1.0 - decay)
            v_fqs = h_q + v_pq - h_q_new
            v_q = q * h
            v_ets = ets * h
            # surface water cannot go below zero: scale its outflows (discharge, evaporation, infiltration)
            inflow = p * h + a_l / a_s * (v_fqs + max(v_fgs, 0.0))
            outflow = v_q / a_s + v_ets + a_l / a_s * max(-v_fgs, 0.0)
            if h_s + inflow - outflow < 0.0 and outflow > 0.0:
                scale = max(h_s + inflow, 0.0) / outflow
                v_q *= scale
                v_ets *= scale
                if v_fgs < 0.0:
                    v_fgs *= scale
            d_g = d_g + (d_v - d_veq) / c_v * h
            d_v = d_v - v_pv + v_etv + v_fgs
            h_q = h_q_new
            h_s = max(h_s + p * h - v_ets + a_l / a_s * (v_fqs + v_fgs) - v_q / a_s, 0.0)  # clip round-off only
            vol_q += v_q
            vol_et += a_l * v_etv + a_s * v_ets
            vol_fqs += a_l * v_fqs
            vol_fgs += a_l * v_fgs
            t += h
            nsub += 1
        q_out[i] = vol_q / dt
        et_out[i] = vol_et / dt
        fqs_out[i] = vol_fqs / dt
        fgs_out[i] = vol_fgs / dt
        states_out[i, 0] = d_v
        states_out[i, 1] = d_g
        states_out[i, 2] = h_q
        states_out[i, 3] = h_s
        w_out[i] = wetness(d_v, c_w)
        nsub_out[i] = nsub
    state[0] = d_v
    state[1] = d_g
    state[2] = h_q
    state[3] = h_s
