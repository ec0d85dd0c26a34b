"""Twin proof of the gauge advice on dommel with the nine crests estimated one by one (W1…W9 and FA).

With the five stations the verdict says W1, W4, W6, W7 and W8 are not identifiable (the thesis' finding,
§4-5-1: only the crests beside a station are), and a twin calibration from the thesis' start values
(every crest 0.15 m low, FA 14) does not recover them. With the gauges the advice chooses among the sides
of the structures, every parameter is identifiable and the same twin calibration recovers every crest
within 1 cm and FA within 0.5. (``rivercal bench advise`` adds the high start, every calculation point as
candidates, 20 random draws of as many gauges, and the on-line scenario PI-Wl.)
"""

from __future__ import annotations

import pytest

from rivercal.analysis.advise import advise, model_candidates
from rivercal.bench.advise import twin_proof
from rivercal.model import load_model
from rivercal.parameters import ParameterSet

pytestmark = pytest.mark.slow

NAMES = ["W1", "W2", "W3", "W4", "W5", "W6", "W7", "W8", "W9", "FA"]


def test_the_advised_gauges_make_every_crest_identifiable_and_recoverable() -> None:
    model = load_model("dommel")
    defined = {p.name: p for p in model.calibration.parameters}
    params = ParameterSet(defined[n] for n in NAMES)
    window = model.calibration.windows["moderate"]
    places = model_candidates(model, "structures", "level")
    result = advise(model, params, window, places, workers=2)
    unseen = {n for n, v in result.before.verdicts.items() if v != "identifiable"}
    assert unseen == {"W1", "W4", "W6", "W7", "W8"}
    assert result.enough is not None and result.enough <= len(unseen)
    assert set(result.after.verdicts.values()) == {"identifiable"}
    chosen = [next(c for c in places if c.id == g) for g in result.chosen]
    advised = twin_proof(model, params, window, chosen, workers=2, starts=("low",))
    assert advised["success"], advised
    assert advised["low"]["worst_crest_error_m"] <= 0.01
    present = twin_proof(model, params, window, [], workers=2, starts=("low",))
    assert not present["success"]
    assert present["low"]["worst_crest_error_m"] > 0.05  # an unseen crest stays far from its truth
