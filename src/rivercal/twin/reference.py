"""The reference study's twin-experiment results, typed in as cited reference data.

Source: the thesis "On-line parameter updating as an optimisation tool for Decision Support Systems"
(``seed/thesis-online-parameter-updating.txt``), Tables 4-5 and 4-6 (F1W0, F0W1), 4-7 and 4-8 (FaWc),
4-9 and 4-10 (FaWcP), 4-11 and 4-12 (FaWcN). Per scenario: the calibrated parameter values, then the
iterations, final cost, RMSE, bias and standard deviation of the errors — the thesis' weighted,
dimensionless values (its weights follow thesis Eq. 2-6, rivercal's default weights are 1/σ², so
costs compare in order of magnitude only). Extracted from the thesis text by a script and checked
against the tables; values exactly as printed (one apparent typo kept: F0W1 H2 RMSE is printed
negative).

The initial model analysis (thesis §4-5-1) is given only as figures (Fig. 4-5, C-1 … C-5, 4-6, 4-7) and
the text that reads them; :data:`THESIS_SENSITIVITY` and :data:`THESIS_IDENTIFIABILITY` hold what that
text states (rankings, which parameters dominate which singular vectors, the signs of correlations, the
verdict), with the sentence each item comes from. :data:`THESIS_FIGURES` gives the figure numbers of every
suite's figures, for captions.
"""

from __future__ import annotations

import statistics

__all__ = ["THESIS", "THESIS_FIGURES", "THESIS_IDENTIFIABILITY", "THESIS_REMARKS", "THESIS_SENSITIVITY",
           "thesis_row", "thesis_summary"]

#: suite → scenario id → (calibrated values by parameter, iterations, cost, RMSE, bias, STD)
THESIS = {
    'F1W0': {
        'H1': ({'F1': 19.9997}, 4, 1.34e-09, 2.93e-06, 2.78e-06, 9.21e-07),
        'H2': ({'F1': 19.9959}, 3, 2.55e-07, 4.04e-05, -3.87e-05, 1.18e-05),
        'M1': ({'F1': 15.9985}, 3, 7.84e-08, 2.24e-05, -2.16e-05, 6.13e-06),
        'M2': ({'F1': 16.0002}, 4, 8.39e-10, 2.32e-06, 2.22e-06, 6.79e-07),
        'L1': ({'F1': 12.0004}, 4, 8.84e-08, 2.38e-05, 6.86e-06, 2.29e-05),
        'L2': ({'F1': 12.0002}, 5, 3.57e-09, 4.78e-06, 4.61e-06, 1.27e-06),
    },
    'F0W1': {
        'H1': ({'W2': 10.75}, 2, 3.79e-08, 2.19e-05, -2.19e-05, 1.59e-07),
        'H2': ({'W2': 10.75}, 2, 8.83e-09, -8.83e-05, -9.09e-08, 5.53e-07),
        'M1': ({'W2': 10.45}, 2, 4.93e-08, 2.49e-05, -2.49e-05, 2.61e-07),
        'M2': ({'W2': 10.45}, 2, 3.57e-08, 2.12e-05, 2.12e-05, 2.22e-07),
        'L1': ({'W2': 10.15}, 2, 4.24e-09, 7.31e-06, -7.31e-06, 6.08e-08),
        'L2': ({'W2': 10.1499}, 2, 2.88e-07, 6.02e-05, 6.02e-05, 5e-07),
    },
    'FaWc': {
        'H1H1': ({'FA': 19.999, 'Wc': 0.8}, 6, 3.81e-08, 7.84e-05, -2.16e-05, 5.16e-05),
        'H1H2': ({'FA': 20.0002, 'Wc': 0.8}, 6, 4.13e-08, 9.3e-05, -3.19e-05, 8.36e-05),
        'H2H1': ({'FA': 19.9992, 'Wc': 0.80001}, 7, 9.69e-08, 0.000144, -8.56e-05, 9.68e-05),
        'H2H2': ({'FA': 19.9995, 'Wc': 0.8}, 5, 1.79e-08, 6.26e-05, 1.75e-06, 5.26e-05),
        'H1M1': ({'FA': 20.0016, 'Wc': 0.59998}, 6, 3.83e-07, 0.000275, 0.000156, 0.000172),
        'H1M2': ({'FA': 19.9989, 'Wc': 0.6}, 6, 7.99e-08, 0.000137, -7.71e-07, 0.000114),
        'H2M1': ({'FA': 19.9951, 'Wc': 0.6}, 8, 1.14e-08, 5.74e-05, -1.45e-05, 4.56e-05),
        'H2M2': ({'FA': 19.9972, 'Wc': 0.6}, 6, 3.52e-07, 0.000224, -0.000111, 0.00014),
        'H1L1': ({'FA': 20.0007, 'Wc': 0.39999}, 6, 5.11e-08, 9.52e-05, 7.77e-05, 3.43e-05),
        'H1L2': ({'FA': 20.009, 'Wc': 0.40009}, 6, 4.66e-06, 0.000818, 0.000238, 0.000412),
        'H2L1': ({'FA': 19.9976, 'Wc': 0.4}, 5, 2.67e-07, 0.000169, -0.000106, 8.08e-05),
        'H2L2': ({'FA': 20.0006, 'Wc': 0.4}, 7, 2.42e-08, 5.72e-05, 4.54e-05, 2.7e-05),
        'M1H1': ({'FA': 15.9999, 'Wc': 0.8}, 6, 6.92e-10, 7.89e-06, -6.41e-06, 3.65e-06),
        'M1H2': ({'FA': 15.9994, 'Wc': 0.8}, 5, 3.73e-08, 5.69e-05, -3.34e-05, 2.44e-05),
        'M2H1': ({'FA': 16.0, 'Wc': 0.8}, 6, 2.07e-09, 1.33e-05, 1.18e-05, 2.85e-06),
        'M2H2': ({'FA': 15.9995, 'Wc': 0.8}, 6, 2.37e-08, 4.62e-05, -3.74e-05, 1.9e-05),
        'M1M1': ({'FA': 15.9999, 'Wc': 0.60001}, 7, 1.15e-08, 3.27e-05, -3.01e-05, 5.68e-06),
        'M1M2': ({'FA': 15.9997, 'Wc': 0.6}, 6, 8.83e-09, 2.99e-05, -2.46e-05, 1.17e-05),
        'M2M1': ({'FA': 15.9999, 'Wc': 0.59999}, 6, 5.69e-09, 2.52e-05, 7.04e-06, 7.67e-06),
        'M2M2': ({'FA': 15.999, 'Wc': 0.60004}, 7, 3.99e-07, 0.000226, -0.000193, 5.14e-05),
        'M1L1': ({'FA': 15.9982, 'Wc': 0.39999}, 5, 3.52e-05, 0.000927, -3.63e-05, 0.000838),
        'M1L2': ({'FA': 16.0015, 'Wc': 0.39998}, 10, 3.31e-07, 0.000208, 0.000178, 6.16e-05),
        'M2L1': ({'FA': 16.0016, 'Wc': 0.40001}, 5, 2.66e-07, 0.000164, 9.61e-05, 7.26e-05),
        'M2L2': ({'FA': 15.9953, 'Wc': 0.39994}, 7, 3.73e-05, 0.00122, -0.000104, 0.000951),
        'L1H1': ({'FA': 11.9999, 'Wc': 0.8}, 6, 3.7e-09, 1.98e-05, 2.3e-06, 6.68e-06),
        'L1H2': ({'FA': 11.9998, 'Wc': 0.8}, 6, 1.96e-08, 4.39e-05, -3.23e-05, 2.29e-05),
        'L2H1': ({'FA': 12.0, 'Wc': 0.8}, 6, 5.82e-10, 6.15e-06, -5.04e-06, 1.81e-06),
        'L2H2': ({'FA': 12.0, 'Wc': 0.8}, 8, 2.09e-09, 1.51e-05, 7.86e-07, 5.45e-06),
        'L1M1': ({'FA': 11.9996, 'Wc': 0.59996}, 6, 2.17e-07, 0.000151, 5.17e-05, 4.79e-05),
        'L1M2': ({'FA': 11.9998, 'Wc': 0.6}, 8, 1.35e-08, 4.09e-05, -3.3e-05, 1.49e-05),
        'L2M1': ({'FA': 12.0001, 'Wc': 0.6}, 6, 1.13e-08, 4.27e-05, 2.13e-05, 3.16e-05),
        'L2M2': ({'FA': 12.0002, 'Wc': 0.6}, 7, 2.67e-08, 6.76e-05, 4.6e-05, 3.87e-05),
        'L1L1': ({'FA': 12.0, 'Wc': 0.40001}, 6, 6.64e-09, 2.34e-05, -2.06e-05, 3.59e-06),
        'L1L2': ({'FA': 11.9999, 'Wc': 0.4}, 7, 2.3e-09, 1.8e-05, -1.53e-05, 5.65e-06),
        'L2L1': ({'FA': 12.0021, 'Wc': 0.40008}, 6, 2.19e-06, 0.000564, -3.71e-06, 0.000234),
        'L2L2': ({'FA': 12.0064, 'Wc': 0.39993}, 7, 1.44e-05, 0.00133, 0.00104, 0.000519),
    },
    'FaWcP': {
        'H1H1': ({'FA': 20.0, 'Wc': 0.8}, 6, 4.21e-08, 9.48e-05, -3.81e-05, 8.58e-05),
        'H1H2': ({'FA': 19.9859, 'Wc': 0.7999}, 5, 3.86e-05, 0.0019, -0.000862, 0.00103),
        'H2H1': ({'FA': 19.9994, 'Wc': 0.8}, 5, 8.76e-08, 0.000123, -5.12e-05, 9.09e-05),
        'H2H2': ({'FA': 20.0025, 'Wc': 0.8}, 5, 1.12e-06, 0.000328, 0.000216, 0.00019),
        'H1L1': ({'FA': 19.9999, 'Wc': 0.4}, 6, 4.73e-09, 3.72e-05, -2.38e-07, 2.64e-05),
        'H1L2': ({'FA': 19.9997, 'Wc': 0.4}, 6, 1.22e-07, 0.000185, -6.32e-05, 0.00016),
        'H2L1': ({'FA': 20.0, 'Wc': 0.4}, 5, 3.84e-08, 9.06e-05, -3.75e-05, 8.21e-05),
        'H2L2': ({'FA': 19.9997, 'Wc': 0.4}, 6, 5.08e-08, 0.000132, -9.02e-06, 0.000122),
        'L1H1': ({'FA': 11.9999, 'Wc': 0.8}, 5, 5.4e-08, 0.000118, -2.12e-05, 0.000104),
        'L1H2': ({'FA': 11.9998, 'Wc': 0.8}, 6, 2.81e-07, 0.000243, -5.25e-05, 0.000229),
        'L2H1': ({'FA': 12.0011, 'Wc': 0.7997}, 6, 1.43e-05, 0.0013, 0.00105, 0.000454),
        'L2H2': ({'FA': 12.0011, 'Wc': 0.8}, 10, 1.58e-06, 0.00038, 0.000254, 0.00021),
        'L1L1': ({'FA': 12.0, 'Wc': 0.4}, 6, 2.32e-07, 0.000224, 4.47e-05, 0.00022),
        'L1L2': ({'FA': 11.9997, 'Wc': 0.4}, 6, 4.73e-07, 0.000318, -1.36e-05, 0.000299),
        'L2L1': ({'FA': 12.0, 'Wc': 0.4}, 7, 3.91e-07, 0.000295, 2.84e-05, 0.000292),
        'L2L2': ({'FA': 11.9999, 'Wc': 0.4}, 7, 2.47e-07, 0.000239, -1.11e-05, 0.000231),
    },
    'FaWcN': {
        'H1H1': ({'FA': 20.0331, 'Wc': 0.7997}, 6, 0.198, 0.157, 0.00283, 0.157),
        'H1H2': ({'FA': 20.0728, 'Wc': 0.8002}, 6, 0.201, 0.159, -0.00204, 0.159),
        'H2H1': ({'FA': 20.0048, 'Wc': 0.8001}, 7, 0.211, 0.159, 0.000528, 0.159),
        'H2H2': ({'FA': 20.0768, 'Wc': 0.799}, 5, 0.2, 0.157, 0.00569, 0.157),
        'H1L1': ({'FA': 19.9611, 'Wc': 0.4007}, 6, 0.216, 0.162, -0.00195, 0.162),
        'H1L2': ({'FA': 20.04, 'Wc': 0.4012}, 6, 0.21, 0.161, 0.00159, 0.161),
        'H2L1': ({'FA': 20.0653, 'Wc': 0.4001}, 5, 0.206, 0.159, -0.000386, 0.159),
        'H2L2': ({'FA': 19.9633, 'Wc': 0.3997}, 11, 0.207, 0.16, -0.00489, 0.16),
        'L1H1': ({'FA': 11.9851, 'Wc': 0.8019}, 12, 0.21, 0.162, 0.000751, 0.162),
        'L1H2': ({'FA': 11.986, 'Wc': 0.8}, 6, 0.196, 0.157, -0.00311, 0.157),
        'L2H1': ({'FA': 11.9957, 'Wc': 0.7994}, 13, 0.205, 0.16, -0.0018, 0.16),
        'L2H2': ({'FA': 12.01, 'Wc': 0.7996}, 22, 0.211, 0.161, 0.00344, 0.161),
        'L1L1': ({'FA': 11.978, 'Wc': 0.3995}, 10, 0.198, 0.157, 0.00092, 0.157),
        'L1L2': ({'FA': 11.9832, 'Wc': 0.4003}, 7, 0.202, 0.156, -0.00396, 0.156),
        'L2L1': ({'FA': 11.9836, 'Wc': 0.4005}, 6, 0.205, 0.158, -0.00335, 0.158),
        'L2L2': ({'FA': 11.9793, 'Wc': 0.4}, 7, 0.199, 0.159, 0.00328, 0.159),
    },
}


def thesis_row(suite: str, scenario: str) -> dict[str, float] | None:
    """The thesis' result for one scenario as a flat dict, or None when the thesis has no such scenario."""
    entry = THESIS.get(suite, {}).get(scenario)
    if entry is None:
        return None
    estimates, iterations, cost, rmse, bias, std = entry
    return {**{f"{k}_estimate": v for k, v in estimates.items()}, "iterations": iterations, "cost": cost,
            "rmse": rmse, "bias": bias, "std_error": std}


def thesis_summary(suite: str, tolerance: dict[str, float] | None = None, *,
                   ids: list[str] | tuple[str, ...] | None = None) -> dict[str, object] | None:
    """Performance indicators of a thesis suite computed from its typed-in table (None: no such suite).

    ``ids`` restricts the summary to these scenarios (for a comparison with a partial run; ids the thesis
    does not have are ignored, and None is returned when none is left).

    Keys as :func:`rivercal.report.twin.suite_summary` where the thesis has the numbers: ``scenarios``,
    ``iterations_median``, ``iterations_max``, ``max_abs_error`` (per parameter, in its unit, from the
    calibrated values and the truths decoded from the scenario ids), ``cost_median``, and ``robustness``
    (share of scenarios within ``tolerance`` of the truth; only with ``tolerance``). The thesis reports
    no model runs or wall times per suite.
    """
    rows = THESIS.get(suite)
    if rows and ids is not None:
        rows = {sid: row for sid, row in rows.items() if sid in set(ids)}
    if not rows:
        return None
    errors: dict[str, list[float]] = {}
    for sid, (estimates, *_rest) in rows.items():
        for name, value in estimates.items():
            errors.setdefault(name, []).append(abs(value - _TRUTHS[name][sid[2 * list(estimates).index(name)]]))
    out: dict[str, object] = {
        "scenarios": len(rows),
        "iterations_median": float(statistics.median(r[1] for r in rows.values())),
        "iterations_max": max(r[1] for r in rows.values()),
        "max_abs_error": {name: max(v) for name, v in errors.items()},
        "cost_median": float(statistics.median(r[2] for r in rows.values())),
    }
    if tolerance is not None:
        n_ok = sum(all(abs(v) <= tolerance[name] + 1e-12 for name, v in zip(errors, vals, strict=True))
                   for vals in zip(*errors.values(), strict=True))
        out["robustness"] = n_ok / len(rows)
    return out


#: True values by parameter and scenario letter (thesis Tables 4-5, 4-7, 4-9, 4-11); k_s in m^(1/3)/s,
#: the crest W2 in m AD, Wc dimensionless.
_TRUTHS = {"F1": {"H": 20.0, "M": 16.0, "L": 12.0}, "FA": {"H": 20.0, "M": 16.0, "L": 12.0},
           "W2": {"H": 10.75, "M": 10.45, "L": 10.15}, "Wc": {"H": 0.8, "M": 0.6, "L": 0.4}}


#: Figure numbers of the thesis for each suite's figures (chapter 4; appendices D-F for the FaWc-type levels).
THESIS_FIGURES = {
    "F1W0": {"convergence": "4-8", "cost": "4-9", "levels": "4-10", "bias": "4-11"},
    "F0W1": {"convergence": "4-12", "cost": "4-13", "levels": "4-14", "bias": "4-15"},
    "FaWc": {"convergence": "4-17/4-18, 4-20/4-21, 4-23/4-24", "cost": "4-16, 4-19, 4-22", "levels": "D-x",
             "bias": "4-25"},
    "FaWcP": {"convergence": "4-27/4-28", "cost": "4-26", "levels": "E-x", "bias": "4-29"},
    "FaWcN": {"convergence": "4-31/4-32", "cost": "4-30", "levels": "F-x", "bias": "4-33"},
}

#: What the thesis says of each suite's efficiency and robustness (§4-5-2 … §4-5-6), quoted.
THESIS_REMARKS = {
    "F1W0": "§4-5-2-1: \"For each scenario, a fast convergence is observed. Within five iterations the actual "
            "friction value is correctly estimated by the OPE tool.\"",
    "F0W1": "§4-5-3-1: \"The crest level is correctly predicted by the OPE tool within two iterations, which is "
            "faster than [...] the friction parameter.\"",
    "FaWc": "§4-5-4-1: \"for all scenarios (in each group) within ten iterations the actual parameter value is "
            "predicted accurately.\"",
    "FaWcP": "§4-5-5-1: \"Only one scenario (L2H2) tends to need more iterations for correctly predicting the actual "
             "parameter values\"",
    "FaWcN": "§4-5-6-1: \"the additive noise causes the OPE tool to execute more iterations for correct prediction "
             "of the actual parameters [...] the scenario L2H2 requires significantly more iterations\"; §6-1: "
             "\"the required computation time is only increased with a factor two\".",
}

#: The sensitivity analysis of thesis §4-5-1 (Fig. 4-5, Figs. C-1 ... C-5), as its text states it.
THESIS_SENSITIVITY = {
    "source": "thesis §4-5-1, Fig. 4-5 and Figs. C-1 ... C-5 (moderate window, Table 4-4 scenarios)",
    # "parameters W2, FA, W3 and W5 have the strongest influence on the objective function values"
    "strongest": ("W2", "FA", "W3", "W5"),
    "strongest_quote": "From this figure it can be observed that parameters W2, FA, W3 and W5 have the strongest "
                       "influence on the objective function values.",
    # per station: does any crest matter (C-1 ... C-5)? the parameter that matters most, where stated
    "stations": {
        "0028": {"figure": "C-1", "crests_matter": True, "top": None},
        "0029": {"figure": "C-2", "crests_matter": False, "top": None},
        "0030": {"figure": "C-3", "crests_matter": False, "top": "FA"},
        "0031": {"figure": "C-4", "crests_matter": False, "top": "FA"},
        "0040": {"figure": "C-5", "crests_matter": True, "top": "FA", "top_crest_low": "W5", "top_crest_high": "W3"},
    },
    "stations_quote": "only location 0028 and 0040 seems to be influenced by a change in the crest level height of "
                      "weirs (see Figure C-1 and Figure C-5). At location 0030, 0031 and 0040 the objective function "
                      "is most affected by the overall bed roughness change [...] for location 0040 the lower "
                      "scenarios 1 and 2 the cost function is most affected by parameter W5, while for the higher "
                      "scenarios parameter W3 is most influential.",
}

#: The identifiability analysis of thesis §4-5-1 (Figs. 4-6 and 4-7), as its text states it.
THESIS_IDENTIFIABILITY = {
    "source": "thesis §4-5-1, Fig. 4-6 (singular value decomposition) and Fig. 4-7 (correlation matrix)",
    # singular vector (1-based, strongest first) -> the parameter(s) that dominate it
    "vectors": {1: ("W2",), 2: ("W3",), 3: ("W5", "FA"), 4: ("W5", "FA"), 5: ("W4",), 6: ("W7",),
                7: ("W1", "W6", "W9"), 8: ("W1", "W6", "W9"), 9: ("W1", "W6", "W9"), 10: ("W8",)},
    "vectors_quote": "The eigenvectors 1, 2, 5, 6 and 10 more or less dominated by the parameters W2, W3, W4, W7 and "
                     "W8, respectively. [...] The eigenvectors 3 and 4 show an influence on the model by the "
                     "combination of parameter W5 and FA, while eigenvectors 7, 8 and 9 represent a combination of "
                     "parameter W1, W6 and W9.",
    # the singular values of vectors 5, 6 and 10 are "(very) low": W4, W7 and W8 are hardly seen
    "weak_vectors": (5, 6, 10),
    # pairs the thesis names as negatively correlated (Fig. 4-7)
    "negative_pairs": (("W1", "W4"), ("FA", "W3"), ("FA", "W5"), ("W2", "W3"), ("W2", "W5"), ("W6", "W7")),
    "correlation_quote": "parameter W1 is negatively correlated with W4. [...] a negative correlation between the "
                         "parameters FA and W2 with W3 and W5 is observed. [...] Lastly, a negative correlation "
                         "between W6 and W7 is noticed.",
    # the conclusion: FA and W2 are identifiable, the other crests are not (hence the cluster Wc, §4-4)
    "identifiable": ("FA", "W2"),
    "not_identifiable": ("W1", "W3", "W4", "W5", "W6", "W7", "W8", "W9"),
    "verdict_quote": "weir parameter W2 is the only weir parameter that has a significant influence the cost "
                     "function. In other words, the other weir parameters are not very identifiable [...] the weir "
                     "parameters are clustered into one parameter",
}
