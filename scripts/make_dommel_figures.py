"""Figures of the ``dommel`` case README: network, rain and runoff, three-month station hydrographs.

Run from the repository root after ``scripts/make_dommel_case.py``::

    python scripts/make_dommel_figures.py

Writes ``network.png``, ``rain_runoff.png`` and ``hydrographs.png`` into ``src/rivercal/cases/dommel/``
and prints the figures quoted in the README (dry-weather and event discharges, run time, balance).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import pandas as pd

from rivercal.hydrology import hourly_forcing, read_knmi_daily
from rivercal.model import load_model
from rivercal.report.figures import plot_network, plot_series

OUT = Path(__file__).resolve().parents[1] / "src" / "rivercal" / "cases" / "dommel"


def main() -> None:
    sim = load_model("dommel")
    case = sim.case
    labels = {t[5:-12]: f"{p.name} {t[5:-12]}"
              for p in case.spec.parameters for t in p.targets if t.startswith("weir:")}
    plot_network(case.network, OUT / "network.png", title="dommel: De Dommel-like weir network (ZL1, ZL12, ZL25)",
                 weir_labels=labels)
    result, _ = sim.simulate()
    plot_series(result.series, OUT / "hydrographs.png", title="dommel, Sep-Nov 2010: station series (true parameters)")

    hourly = hourly_forcing(read_knmi_daily(OUT / "meteo" / "etmgeg_370_20100901-20101201.txt"))
    inflow = pd.DataFrame({k: v for k, v in sim.forcing.items() if k.startswith(("lateral:", "boundary:Q_"))})
    total = inflow.sum(axis=1)
    fig, (ax_p, ax_q) = plt.subplots(2, 1, figsize=(12, 6), sharex=True, height_ratios=[1, 2])
    p = hourly["P"].loc[case.start:case.end]
    ax_p.bar(p.index, p.to_numpy(), width=1 / 24, color="#2b6cb0")
    ax_p.invert_yaxis()
    ax_p.set_ylabel("rain (mm/h)")
    ax_p.set_title("KNMI Eindhoven 2010, disaggregated to hours, and the resulting inflows")
    ax_q.plot(total.index, total.to_numpy(), color="#2f855a", lw=1.2, label="all catchments (130 km²), m³/s")
    ax_q.plot(result.series.index, result.series["0029.Q"], color="#c05621", lw=1.2, label="discharge at 0029, m³/s")
    for name, (a, b) in {"moderate": ("2010-09-27", "2010-10-04"), "extreme": ("2010-11-08", "2010-11-15")}.items():
        ax_q.axvspan(pd.Timestamp(a, tz="UTC"), pd.Timestamp(b, tz="UTC"), color="0.85", zorder=0)
        ax_q.annotate(f"{name} window", (pd.Timestamp(a, tz="UTC"), ax_q.get_ylim()[1] * 0.9), fontsize=8)
    ax_q.set_ylabel("discharge (m³/s)")
    ax_q.legend(loc="upper left")
    ax_q.grid(alpha=0.3)
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(OUT / "rain_runoff.png", dpi=110)
    plt.close(fig)

    q = result.series["0029.Q"]
    dry = q.loc["2010-09-01":"2010-09-06"]
    nov = q.loc["2010-11-08":"2010-11-15"].max()
    print(f"0029.Q: dry weather early Sep {dry.min():.2f}-{dry.max():.2f} m³/s; "
          f"1-7 Nov mean {q.loc['2010-11-01':'2010-11-07'].mean():.2f}; 8-15 Nov peak {nov:.2f}")
    print(f"total inflow: dry early Sep {total.loc['2010-09-01':'2010-09-06'].mean():.2f}, "
          f"peak Nov {total.loc['2010-11-08':'2010-11-15'].max():.2f} m³/s")
    print(f"rain Sep-Nov {p.sum():.1f} mm; run {result.wall_time:.2f} s; balance {result.balance.relative_error:.1e}")


if __name__ == "__main__":
    main()
