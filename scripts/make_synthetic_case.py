"""Generate the packaged ``synthetic`` case (the engine benchmark network).

A looped lowland network of weir-controlled streams: an upper reach ``M`` that bifurcates into two
parallel reaches ``A`` and ``B``, which join again with a tributary ``T`` and continue as ``C`` to
a rating-curve outlet; 11 weirs, a culvert, 10 laterals, about 460 calculation points. The forcing
is synthetic (a base flow and two storm events) and deterministic.

Run from the repository root::

    python scripts/make_synthetic_case.py

It rewrites ``src/rivercal/cases/synthetic/``. The files are committed; rerun only to change them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

OUT = Path(__file__).resolve().parents[1] / "src" / "rivercal" / "cases" / "synthetic"
START = pd.Timestamp("2020-01-01T00:00:00Z")
DAYS = 14

# branch id: (from, to, length m, bed up, bed down, profile, weirs [(chainage, crest above bed)])
BRANCHES = {
    "M": ("N0", "N1", 9000.0, 14.0, 9.5, "trap6", [(1500, 1.1), (4500, 1.1), (7500, 1.0)]),
    "A": ("N1", "N2", 6000.0, 9.5, 6.5, "trap4", [(2000, 1.0), (4200, 1.0)]),
    "B": ("N1", "N2", 7000.0, 9.5, 6.5, "trap3", [(2500, 1.0), (5000, 0.9)]),
    "T": ("N4", "N2", 6000.0, 9.0, 6.5, "trap3", [(3000, 0.9)]),
    "C": ("N2", "N3", 12000.0, 6.5, 1.0, "trap8", [(3000, 1.2), (6500, 1.2), (9500, 1.2)]),
}
NODES = {"N0": (0, 0), "N1": (9000, 0), "N2": (15000, 0), "N3": (27000, 0), "N4": (19000, -5000)}
GEOMETRY = {"A": [(9000, 0), (12000, 1500), (15000, 0)], "B": [(9000, 0), (12000, -1500), (15000, 0)]}
PROFILES = [
    ("trap3", 3.0, 1.5), ("trap4", 4.0, 1.5), ("trap6", 6.0, 1.5), ("trap8", 8.0, 1.5),
]
LATERALS = [("M", 800), ("M", 3000), ("M", 6000), ("A", 1000), ("A", 5000), ("B", 3500),
            ("T", 1500), ("C", 1500), ("C", 5000), ("C", 8000)]


def _event(t_hours: np.ndarray, peak_hour: float, width: float) -> np.ndarray:
    x = np.clip((t_hours - peak_hour) / width + 1.0, 0.0, None)
    return x**2 * np.exp(2.0 * (1.0 - x))


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    times = pd.date_range(START, periods=DAYS * 24 + 1, freq="h")
    th = np.arange(times.size, dtype=float)
    shape = _event(th, 60.0, 18.0) + 0.6 * _event(th, 200.0, 24.0)
    forcing = pd.DataFrame(index=times)
    forcing["Q_N0"] = 0.8 + 4.0 * shape
    forcing["Q_N4"] = 0.3 + 1.5 * _event(th, 66.0, 14.0)
    for k in range(len(LATERALS)):
        forcing[f"L{k + 1}"] = 0.05 + 0.4 * shape * (0.6 + 0.1 * k)
    forcing.index = forcing.index.strftime("%Y-%m-%dT%H:%M:%SZ")
    forcing.index.name = "time"
    forcing.to_csv(OUT / "forcing.csv", float_format="%.4f")

    lines = [
        "# Synthetic benchmark network: see scripts/make_synthetic_case.py (generated file).",
        "[case]",
        'name = "synthetic"',
        'description = "Looped lowland weir network, 11 weirs, 1 culvert, 10 laterals; synthetic storms."',
        f'start = "{START.strftime("%Y-%m-%dT%H:%M:%SZ")}"',
        f'end = "{(START + pd.Timedelta(days=DAYS)).strftime("%Y-%m-%dT%H:%M:%SZ")}"',
        "",
        "[engine]",
        "dt = 60.0",
        "output_interval = 3600.0",
        "",
        "[initial]",
        "depth = 1.0",
        "spinup = 48.0",
        "",
        "[friction]",
        'type = "strickler"',
        "value = 25.0",
        "",
    ]
    for pid, b, m in PROFILES:
        lines += ["[[profiles]]", f'id = "{pid}"', 'type = "trapezoidal"', f"bottom_width = {b}",
                  f"side_slope = {m}", "height = 2.5", ""]
    for nid, (x, y) in NODES.items():
        lines += ["[[nodes]]", f'id = "{nid}"', f"x = {x}", f"y = {y}", ""]
    weir_no = 0
    weirs = []
    for bid, (fr, to, length, zb0, zb1, prof, wl) in BRANCHES.items():
        lines += ["[[branches]]", f'id = "{bid}"', f'from_node = "{fr}"', f'to_node = "{to}"',
                  f"length = {length}", "dx = 100.0"]
        if bid == "B":
            lines += ['friction = { type = "manning", value = 0.04 }']
        if bid in GEOMETRY:
            lines += ["geometry = [" + ", ".join(f"[{x}, {y}]" for x, y in GEOMETRY[bid]) + "]"]
        lines += [
            "cross_sections = [",
            f'  {{ chainage = 0.0, profile = "{prof}", bed_level = {zb0} }},',
            f'  {{ chainage = {length}, profile = "{prof}", bed_level = {zb1} }},',
            "]", "",
        ]
        for ch, above in wl:
            weir_no += 1
            bed = zb0 + (zb1 - zb0) * ch / length
            weirs.append((f"W{weir_no}", bid, ch, round(bed + above, 3)))
    for wid, bid, ch, crest in weirs:
        lines += ["[[weirs]]", f'id = "{wid}"', f'branch = "{bid}"', f"chainage = {ch:.1f}",
                  f"crest_level = {crest}", "crest_width = 4.0", "discharge_coefficient = 1.0", ""]
    lines += ["[[culverts]]", 'id = "K1"', 'branch = "T"', "chainage = 5000.0", 'shape = "circular"',
              "diameter = 1.5", "invert_level = 6.95", "length = 20.0", ""]
    lines += ["[[boundaries]]", 'id = "Qup"', 'node = "N0"', 'type = "discharge"',
              'series = { file = "forcing.csv", column = "Q_N0" }', "",
              "[[boundaries]]", 'id = "Qtrib"', 'node = "N4"', 'type = "discharge"',
              'series = { file = "forcing.csv", column = "Q_N4" }', "",
              "[[boundaries]]", 'id = "outlet"', 'node = "N3"', 'type = "rating"',
              "rating = { levels = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0], discharges = [0.0, 1.0, 3.5, 7.5, 12.5, 25.0] }",
              ""]
    for k, (bid, ch) in enumerate(LATERALS):
        lines += ["[[laterals]]", f'id = "L{k + 1}"', f'branch = "{bid}"', f"chainage = {ch:.1f}",
                  f'series = {{ file = "forcing.csv", column = "L{k + 1}" }}', ""]
    stations = [("S1", "W2"), ("S2", "W5"), ("S3", "W7"), ("S4", "W10"), ("S5", "K1")]
    for sid, wid in stations:
        lines += ["[[stations]]", f'id = "{sid}"', f'structure = "{wid}"', 'quantities = ["h_up", "h_down", "Q"]', ""]
    lines += ["[[stations]]", 'id = "S6"', 'branch = "C"', "chainage = 11000.0", 'quantities = ["h", "Q"]', ""]
    (OUT / "case.toml").write_text("\n".join(lines), encoding="utf-8")
    (OUT / "README.md").write_text(
        "# synthetic\n\nGenerated by `scripts/make_synthetic_case.py`: a looped lowland network of weir-"
        "controlled trapezoidal streams (5 branches, 11 weirs, a circular culvert, 10 laterals, a Q(h) "
        "outlet) with synthetic storm hydrographs. It is the engine benchmark network of "
        "`rivercal bench engine` and the case `make demo` simulates until the De Dommel case exists.\n",
        encoding="utf-8",
    )


if __name__ == "__main__":
    main()
