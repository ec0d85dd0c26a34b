"""
From installation to a calibrated model
=======================================

This tutorial takes you from installing rivercal to a calibrated river model in Python, on the default
case ``dommel``: a De Dommel-like network of streams and nine weirs, driven by the real KNMI weather of
autumn 2010. You will

1. load the case and simulate it,
2. choose the parameters to estimate and set up observations,
3. calibrate with DuD and read the result (estimates, standard deviations, correlation),
4. check whether the observations can see the parameters at all (identifiability),
5. run three daily cycles of the on-line service and read what it stored.

Everything on this page was computed when the documentation was built, so the numbers and figures are
those of the version you are reading about.

Install
-------
rivercal needs Python 3.11 or later. In a copy of the repository::

    python -m venv .venv
    .venv/bin/pip install .                 # the engine, calibration, on-line service, reports
    .venv/bin/pip install ".[dashboard]"    # optional extras: dashboard, swmm, bmi, fews, dhydro

The first model run compiles the engine with numba (about a minute on a slow machine); later runs load
the compiled code from the cache.
"""

# %%
# Load the case
# -------------
# :func:`rivercal.load_model` takes the name of a packaged case, a case folder or a ``model.toml``, and
# returns a model of the model contract. For a case it is the embedded engine,
# an :class:`~rivercal.models.EmbeddedModel`. ``import rivercal`` itself is light: the engine is
# imported on first use.

import matplotlib.pyplot as plt

import rivercal

model = rivercal.load_model("dommel")
model

# %%
# The model declares the quantities a calibration may set, with their units and bounds: the crest
# level of every weir (m AD; no bound of its own, ±inf: the case refuses a crest below the bed) and the bed
# friction (Strickler k_s in m^(1/3)/s; a branch without its own friction shows the global value it inherits).

model.quantities_frame()

# %%
# Simulate
# --------
# :meth:`~rivercal.engine.Simulator.simulate` runs the model with the given quantities (the others keep the
# case's values) and returns the station series and the state at the end. Here: the case's own
# parameters up to the end of the case's "moderate" calibration window.

window = model.calibration.windows["moderate"]
result, state = model.simulate(end=window.end)
levels = result.series[["0028.h_up", "0029.h_up", "0030.h_up", "0031.h_up"]]
ax = levels.plot(figsize=(8, 3.5), ylabel="level upstream of the weir (m AD)", xlabel="")
ax.set_title("dommel: simulated levels with the case's parameters")
plt.tight_layout()

# %%
# Parameters
# ----------
# A calibration estimates :class:`~rivercal.parameters.Parameter` objects: each has physical bounds, an
# initial value, the first perturbation DuD takes, and the model quantities it sets. The case ships a
# set of them (``case.toml``, section ``[[parameters]]``): ``FA`` is the global bed friction and ``Wc``
# one number in [0, 1] that places every adjustable weir's crest between its own lowest and highest
# level (a *cluster*).

params = rivercal.ParameterSet([model.calibration.parameter("FA"), model.calibration.parameter("Wc")])
params.to_frame()

# %%
# Observations
# ------------
# Observations are series named like the simulated ones, ``"<station>.<quantity>"``, in m AD (levels)
# or m³/s (discharges), each with a standard deviation σ that sets its weight (W = 1/σ²).
#
# Here they come from a *twin experiment*: the model itself, run with "true" parameters (FA = 20,
# Wc = 0.6), plus white noise of ±2.5 cm on levels and ±0.1 m³/s on discharges. Because the truth is
# known, you can see how close the calibration gets. With measured data you would build the same
# object from a DataFrame, as below, or read a CSV or Delft-FEWS PI-XML file
# (:func:`rivercal.io.read_observations_csv`, :func:`rivercal.io.read_pixml`).

truth = rivercal.twin_truth(model, params.quantities({"FA": 20.0, "Wc": 0.6}), window, noise="white", seed=1)
frame = truth.observations.to_frame()  # a DataFrame: one column per series, UTC times
observations = rivercal.ObservationSet.from_frame(frame, sigma={"h_up": 0.025, "h_down": 0.025, "Q": 0.1},
                                                  source="twin FA=20, Wc=0.6")
observations

# %%
observations.summary()

# %%
# The calibration problem
# -----------------------
# A :class:`~rivercal.problem.CalibrationProblem` ties model, parameters and observations together over
# the window. Each run starts a day before the window (the warm-up) from a state computed with the
# initial parameters, and the problem returns the weighted residuals r = (y − ŷ)/σ whose sum of squares
# is the cost S of the thesis' Eq. 2-3.

problem = rivercal.CalibrationProblem(model, params, observations, window)
problem

# %%
# Calibrate with DuD
# ------------------
# :func:`rivercal.calibrate` runs an optimiser on the problem; ``"dud"`` (Doesn't Use Derivatives) is a
# secant Gauss-Newton method that needs about one model run per parameter and iteration. The
# result holds the estimates in physical units with their standard deviations (thesis Eq. 2-12) and
# correlation (Eq. 2-13).

calibration = rivercal.calibrate(problem, "dud", workers=1)
print(calibration.fit_report())

# %%
# The same as tables:

calibration.to_frame()

# %%
calibration.correlation_frame()

# %%
# Both estimates land within a few standard deviations of the truth (FA = 20, Wc = 0.6). How DuD got
# there, iteration by iteration:

history = calibration.history_frame()
fig, axes = plt.subplots(1, 3, figsize=(9, 3))
history["cost"].plot(ax=axes[0], marker="o", logy=True, title="cost S")
history["FA"].plot(ax=axes[1], marker="o", title="FA (m^(1/3)/s)")
history["Wc"].plot(ax=axes[2], marker="o", title="Wc (-)")
axes[1].axhline(20.0, color="grey", ls="--", label="truth")
axes[2].axhline(0.6, color="grey", ls="--", label="truth")
axes[2].legend()
plt.tight_layout()

# %%
# And the calibrated model beside the observations at one station:

x_hat = params.to_x(calibration.estimates)
fitted = problem.simulate(x_hat).series
station = "0030.h_up"
fig, ax = plt.subplots(figsize=(8, 3))
observations[station].to_series().plot(ax=ax, style=".", ms=3, color="grey", label="observed (twin)")
problem.simulate(problem.x0).series[station].loc[window.start:].plot(ax=ax, label="initial parameters")
fitted[station].loc[window.start:].plot(ax=ax, label="calibrated")
ax.set_ylabel("level (m AD)")
ax.set_title(f"{station}: before and after calibration")
ax.legend()
plt.tight_layout()

# %%
# Identifiability
# ---------------
# Before trusting an estimate, ask whether the observations can see the parameter at all.
# :func:`rivercal.identifiability` computes the Jacobian of the weighted residuals at a point, its
# singular values and vectors (each parameter scaled by its range) and the identifiability index of
# Doherty and Hunt (2009), and gives a verdict per parameter.
#
# Take the calibrated friction and two single weirs: ``W2`` (weir ZL1-3014, with a station just
# upstream) and ``W1`` (weir ZL1-5, far from any station).

params3 = rivercal.ParameterSet([model.calibration.parameter(n) for n in ("FA", "W2", "W1")])
params3 = params3.with_initial({"FA": calibration.estimates["FA"]})
problem3 = rivercal.CalibrationProblem(model, params3, observations, window)
ident = rivercal.identifiability(problem3, workers=1)
ident.verdict[["verdict", "index", "max_correlation", "top_station"]]

# %%
# The verdict in words (:mod:`rivercal.report.identifiability`):

from rivercal.report.identifiability import text

print(text(ident))

# %%
# The singular values say how strongly the observations react to each combination of parameters; a
# value near zero is a direction the data cannot see.

ident.singular_frame()

# %%
# The on-line service
# -------------------
# In operation, rivercal re-estimates parameters every day over the last week of observations, starting
# from yesterday's estimate, and keeps everything in a store (SQLite). A cycle's estimate is used only
# if it passes the guardrails: the identifiability gate holds a parameter that the window cannot see,
# a change bound limits a step, and an estimate that moves more than ``alert_k`` σ raises an alert.
#
# Here the "true" river's bed friction jumps from 16 to 25 m^(1/3)/s on 2010-11-01 (vegetation mowed,
# scenario PI-Fg of the thesis' chapter 5), while the model starts at 16. Three daily cycles, from the
# day after the change, each estimating the friction ``FA`` alone (the service's default also estimates
# the crest shift ``Wd``) over a window of three days instead of the week (to keep the tutorial quick; the
# default ``window="7D"`` is the thesis' choice):

import tempfile
from pathlib import Path

from rivercal.twin import practical_truth

folder = Path(tempfile.mkdtemp())
config = rivercal.OnlineConfig(parameters=("FA",), window="3D", workers=1)
store = rivercal.Store(folder / "run.sqlite")
service = rivercal.OnlineService(model, store, "tutorial", config, first_issue="2010-11-02")
last_issue = service.schedule.first_issue + 2 * service.period
scenario = practical_truth(model, "PI-Fg", *service.data_period(last_issue), noise="white", seed=2,
                           series=service.series)
store.ingest(scenario.observations, source="twin:PI-Fg")
for outcome in service.replay(last_issue):
    print(outcome.cycle, outcome.issue_time, outcome.status, outcome.accepted, outcome.held or "")

# %%
# Reading the store
# -----------------
# The store keeps the cycles, the estimates with σ and whether they were accepted, the alerts, the
# forecasts of the updated model and of the fixed DSS, and their scores once the observations arrive.

store.cycles(service.run)[["cycle", "issue_time", "status", "model_runs", "wall_time_s", "cost_before", "cost_after"]]

# %%
store.estimates(service.run)[["cycle", "parameter", "value", "std", "accepted", "reason"]]

# %%
store.alerts(service.run)[["cycle", "parameter", "kind", "message"]]

# %%
# Every cycle forecasts 48 h ahead with the updated model and with the DSS (the model as it was). Here
# the forecasts of the last cycle against the twin truth at one station:

forecasts = store.forecasts(service.run, cycle=int(store.cycles(service.run)["cycle"].max()), series=[station])
fig, ax = plt.subplots(figsize=(8, 3))
for kind, group in forecasts.groupby("kind"):
    ax.plot(group["time"], group["value"], label=f"forecast: {kind}")
seen = scenario.observations[station].to_series()
seen.loc[forecasts["time"].min():forecasts["time"].max()].plot(ax=ax, style=".", ms=3, color="grey",
                                                               label="observed (twin)")
ax.set_ylabel("level (m AD)")
ax.set_title(f"{station}: 48 h forecasts of the last cycle")
ax.legend()
plt.tight_layout()

# %%
store.close()

# %%
# Next steps
# ----------
# - The same from the command line: ``rivercal calibrate dommel --params FA,Wc --window moderate
#   --twin FA=20,Wc=0.6`` and ``rivercal online dommel --scenario PI-Fg ...`` (see the CLI reference).
# - :doc:`/howto/index`: your own network, a D-HYDRO model, an external model, the daily service,
#   Delft-FEWS, the dashboard.
# - :doc:`/explanation/index`: the numerical scheme, the optimisers, identifiability and the gate.
