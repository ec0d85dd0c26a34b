"""Dellen as imported against D-HYDRO's own levels, after the spin-up day.

The import is driven by the lateral inflows and structure settings of D-HYDRO's coupled 7-day run
(``rivercal bench dhydro``); its levels are compared with the levels D-Flow FM computed at 144 locations (6
observation points and 138 laterals), every 10 minutes, from the second day on (the model starts from 1 m of
water everywhere). A dead end stores the water of a whole link, as D-Flow FM's dxDoubleAt1DEndNodes does: without
it the polder's levels rose 1.5 cm too fast by the end of the week. Over the whole week, spin-up included, the
levels are within 5 cm (median) of D-HYDRO's.
"""

from __future__ import annotations

import numpy as np
import pytest

from rivercal.bench.dhydro import compare_dellen
from tests.run_artefacts import dellen
from tests.shared_data import shared_model


@pytest.mark.slow
def test_dellen_is_within_a_centimetre_of_dhydro_after_the_spin_up_day(tmp_path) -> None:
    # the run's shared import (the same command as compare_dellen's own import), not a second one
    result = compare_dellen(shared_model("dhydro-dellen"), case=dellen(tmp_path / "case"))
    summary = result.summary()
    assert summary["locations"] == 144
    assert np.isfinite(result.series.to_numpy()).all()
    assert summary["rmse_median_m"] <= 0.05 and summary["rmse_p90_m"] <= 0.10  # the whole week, spin-up included
    after = summary["after_spinup"]
    worst = result.table.sort_values("rmse_after_spinup_m", ascending=False).head(10)
    assert after["median"] <= 0.010, worst
    assert after["p90"] <= 0.030, worst
    assert after["max"] <= 0.050, worst
    assert result.balance_error < 1e-6
