"""Library plotting writes its files without touching the user's matplotlib backend or importing pyplot.

A notebook user's backend must stay what it was after rivercal draws a figure. The check runs in a
fresh interpreter (other tests may have imported pyplot) that picks the 'svg' backend first, then calls
plotting functions of every plotting module and looks at the backend and at ``sys.modules``.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

SCRIPT = textwrap.dedent("""
    import sys
    import matplotlib
    matplotlib.use("svg")
    import numpy as np
    import pandas as pd

    from rivercal.analysis.figures import plot_bias
    from rivercal.case import load_case
    from rivercal.report.figures import plot_convergence, plot_cost, plot_network, plot_series
    from rivercal.report.online import _scores_figure

    out = __import__("pathlib").Path(sys.argv[1])
    case = load_case("synthetic")
    times = pd.date_range("2020-01-01", periods=6, freq="h", tz="UTC")
    series = pd.DataFrame({"S1.h_up": np.linspace(1, 2, 6), "S1.Q": np.linspace(3, 4, 6)}, index=times)
    history = [{"iteration": i, "cost": 10.0 / (i + 1), "FA": 16 + i} for i in range(4)]
    moving = pd.DataFrame({"time": times, "bias": np.linspace(0, 1, 6), "threshold": 0.5,
                           "significant": [False] * 3 + [True] * 3, "series": "S1.h_up"})
    scores = pd.DataFrame({"series": ["S1.h_up"] * 2, "kind": ["dss", "updated"], "lead_to_h": [6.0, 6.0],
                           "rmse": [0.02, 0.01]})
    written = [plot_network(case.network, out / "net.png"), plot_series(series, out / "series.png"),
               plot_convergence(history, ["FA"], out / "conv.png"), plot_cost(history, out / "cost.png"),
               plot_bias(moving, out / "bias.png"), _scores_figure(scores, out / "scores.png")]
    assert all(p.stat().st_size > 1000 for p in written), written
    print(matplotlib.get_backend(), "matplotlib.pyplot" in sys.modules)
""")


def test_plotting_leaves_the_backend_alone(tmp_path: Path) -> None:
    run = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["svg", "False"]
    assert (tmp_path / "net.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
