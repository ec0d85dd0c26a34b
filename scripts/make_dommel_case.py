"""Generate the packaged ``dommel`` case: a De Dommel-like weir network north of Tilburg/Oisterwijk.

The reference study (thesis §4-2) used a SOBEK model of Waterschap De Dommel that is not public.
This script builds a network faithful to everything the thesis states about it:

- three streams named after its weir ids: ``ZL1`` (main stream, 14 km), ``ZL12`` (a parallel branch
  of 5 km that leaves ZL1 at a bifurcation just upstream of ZL1-4018 and rejoins it at chainage
  9820, so the ZL1 section that holds W4 is ``Nriv_ZL_1_9820``) and ``ZL25`` (9 km, a tributary that
  joins ZL1 between stations 0030 and 0031);
- weir ids carry their stream chainage in metres; the nine adjustable weirs of thesis Table 4-2
  with the crest levels of the AVG row of Table 4-4; the fixed weirs of the monitoring stations
  0028 (at ZL1-3014, which is W2), 0040 (ZL1-4018), 0029 (ZL1-8052), 0030 (ZL1-11524) and 0031
  (ZL1-13409); 0040 and W5 (ZL12-45) sit just downstream of the bifurcation and share the flow;
- global friction Strickler k_s = 16 m^(1/3)/s; trapezoidal main channels of 3–8 m bottom width with
  a floodplain above the banks (ZW profiles); beds 0.85–1.1 m below the crests (and at least 0.1 m
  below the Table 4-2 minimum crest);
- the two upstream inflows and 14 laterals from sub-catchments (ha; 150 km² in total) whose runoff
  the rainfall-runoff model of :mod:`rivercal.hydrology` computes from KNMI Eindhoven 2010 weather.

Run from the repository root: ``python scripts/make_dommel_case.py``; it rewrites
``src/rivercal/cases/dommel/case.toml``. The fixed-weir crests, beds, widths and catchment areas are
our choices (the thesis does not give them); the case README lists them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "src" / "rivercal" / "cases" / "dommel"


@dataclass(frozen=True)
class WeirSpec:
    """A weir: stream, stream chainage (m), crest (m AD), crest width (m), calibration name, bounds (m AD)."""

    stream: str
    chainage: float
    crest: float
    width: float
    name: str | None = None
    zmin: float | None = None
    zmax: float | None = None

    @property
    def id(self) -> str:
        return f"{self.stream}-{int(self.chainage)}"


# Thesis Table 4-2 (bounds) and Table 4-4 AVG row (crests); fixed (station) weirs: our choice.
WEIRS = [
    WeirSpec("ZL1", 5, 10.82, 5.0, "W1", 9.90, 11.74),
    WeirSpec("ZL1", 3014, 10.45, 6.5, "W2", 9.80, 11.10),
    WeirSpec("ZL1", 4018, 9.20, 4.0),  # station 0040
    WeirSpec("ZL1", 5126, 8.40, 5.0, "W3", 7.39, 8.80),
    WeirSpec("ZL1", 5930, 7.145, 5.0, "W4", 6.84, 7.45),
    WeirSpec("ZL1", 8052, 6.30, 6.0),  # station 0029
    WeirSpec("ZL1", 11524, 5.40, 7.0),  # station 0030
    WeirSpec("ZL1", 13409, 4.40, 8.0),  # station 0031
    WeirSpec("ZL12", 45, 9.15, 3.0, "W5", 8.66, 9.80),
    WeirSpec("ZL12", 1880, 7.20, 3.0, "W6", 6.73, 8.00),
    WeirSpec("ZL12", 4711, 6.75, 3.5, "W7", 5.87, 7.30),
    WeirSpec("ZL25", 6292, 5.78, 5.0, "W8", 5.16, 6.53),
    WeirSpec("ZL25", 8463, 4.60, 6.0, "W9", 4.13, 5.40),
]
STATIONS = {"0028": "ZL1-3014", "0040": "ZL1-4018", "0029": "ZL1-8052", "0030": "ZL1-11524", "0031": "ZL1-13409"}

# stream: length (m), bed at the upstream and downstream end (m AD), profile by stream chainage
STREAMS = {
    "ZL1": dict(length=14000.0, bed_up=9.95, bed_down=3.20,
                profiles=[(0.0, "zl1_a"), (3990.0, "zl1_b"), (9820.0, "zl1_c")]),
    "ZL12": dict(length=5000.0, bed_up=8.30, bed_down=4.95, profiles=[(0.0, "zl12")]),
    "ZL25": dict(length=9000.0, bed_up=7.60, bed_down=3.75, profiles=[(0.0, "zl25")]),
}
# ZW profiles: trapezoidal main channel (bottom width b, side slope m, bank height hb) and a floodplain
# (flow width +2·fp_flow, storage width +2·fp_store) above the banks.
PROFILES = {
    "zl1_a": dict(b=5.0, m=1.5, hb=2.5, fp_flow=3.0, fp_store=25.0),
    "zl1_b": dict(b=6.0, m=1.5, hb=2.3, fp_flow=4.0, fp_store=30.0),
    "zl1_c": dict(b=12.0, m=1.5, hb=2.8, fp_flow=5.0, fp_store=40.0),
    "zl12": dict(b=3.5, m=1.5, hb=2.2, fp_flow=3.0, fp_store=25.0),
    "zl25": dict(b=6.0, m=1.5, hb=2.8, fp_flow=3.0, fp_store=25.0),
}
# connection nodes: stream and stream chainage (m)
NODES = {
    "ZL1_up": ("ZL1", 0.0),
    "ZL1_3030": ("ZL1", 3030.0),
    "bif_ZL12": ("ZL1", 3990.0),
    "conf_ZL12": ("ZL1", 9820.0),
    "conf_ZL25": ("ZL1", 12800.0),
    "ZL1_out": ("ZL1", 14000.0),
    "ZL25_up": ("ZL25", 0.0),
}
# branches: id, stream, start and end stream chainage (m), from and to node
BRANCHES = [
    ("ZL1_0000_3030", "ZL1", 0.0, 3030.0, "ZL1_up", "ZL1_3030"),
    ("ZL1_3030_3990", "ZL1", 3030.0, 3990.0, "ZL1_3030", "bif_ZL12"),  # F1: just downstream of ZL1-3014
    ("Nriv_ZL_1_9820", "ZL1", 3990.0, 9820.0, "bif_ZL12", "conf_ZL12"),
    ("ZL1_9820_12800", "ZL1", 9820.0, 12800.0, "conf_ZL12", "conf_ZL25"),
    ("ZL1_12800_14000", "ZL1", 12800.0, 14000.0, "conf_ZL25", "ZL1_out"),
    ("ZL12", "ZL12", 0.0, 5000.0, "bif_ZL12", "conf_ZL12"),
    ("ZL25", "ZL25", 0.0, 9000.0, "ZL25_up", "conf_ZL25"),
]
# sub-catchments: id, area (ha), and where their runoff enters (a boundary or a stream chainage)
CATCHMENTS = [
    ("ZL1_upstream", 2400.0, ("boundary", "ZL1_up")),
    ("ZL25_upstream", 2000.0, ("boundary", "ZL25_up")),
    ("C01", 520.0, ("ZL1", 1500.0)), ("C02", 610.0, ("ZL1", 2600.0)), ("C03", 480.0, ("ZL1", 4700.0)),
    ("C04", 700.0, ("ZL1", 6900.0)), ("C05", 560.0, ("ZL1", 9200.0)), ("C06", 830.0, ("ZL1", 10700.0)),
    ("C07", 640.0, ("ZL1", 12300.0)), ("C08", 450.0, ("ZL1", 13800.0)), ("C09", 380.0, ("ZL12", 1000.0)),
    ("C10", 420.0, ("ZL12", 3300.0)), ("C11", 900.0, ("ZL25", 2000.0)), ("C12", 760.0, ("ZL25", 4500.0)),
    ("C13", 690.0, ("ZL25", 7400.0)), ("C14", 660.0, ("ZL25", 8800.0)),
]
# map layout (local metric grid, m): stream centre lines as polylines by stream chainage fraction
LAYOUT = {
    "ZL1": [(0.0, 0.0), (3000.0, 600.0), (4000.0, 700.0), (7000.0, 300.0), (9700.0, 1200.0),
            (12600.0, 1800.0), (13800.0, 2000.0)],
    "ZL12": [(4000.0, 700.0), (5200.0, 2300.0), (7600.0, 2700.0), (9000.0, 2300.0), (9700.0, 1200.0)],
    "ZL25": [(7600.0, -6500.0), (9200.0, -4800.0), (10400.0, -2600.0), (11700.0, -800.0), (12600.0, 1800.0)],
}


def stream_bed(stream: str) -> list[tuple[float, float]]:
    """Bed (stream chainage m, level m AD) of a stream, never rising in the flow direction.

    At each weir the bed lies 0.85 m below the crest and at least 0.1 m below the Table 4-2 minimum
    crest (b_k). Just downstream of weir k (12 m) it has dropped to
    max(b_k - 0.4, b_{k+1} + 0.2 m/km × distance to the next weir), but never above b_k, and it
    declines linearly to b_{k+1}; the stream ends meet the given end beds.
    """
    spec = STREAMS[stream]
    weirs = sorted((w for w in WEIRS if w.stream == stream), key=lambda w: w.chainage)
    at = [min(w.crest - 0.85, (w.zmin if w.zmin is not None else w.crest) - 0.1) for w in weirs]
    pts: list[tuple[float, float]] = [(0.0, max(spec["bed_up"], at[0]) if weirs[0].chainage < 50 else spec["bed_up"])]
    for k, w in enumerate(weirs):
        if w.chainage > pts[-1][0] + 1.0:
            pts.append((w.chainage, min(at[k], pts[-1][1])))
        else:
            pts[-1] = (pts[-1][0], at[k])
        nxt = at[k + 1] if k + 1 < len(weirs) else spec["bed_down"]
        nxt_ch = weirs[k + 1].chainage if k + 1 < len(weirs) else spec["length"]
        after = min(at[k], max(at[k] - 0.4, nxt + 0.0002 * (nxt_ch - w.chainage - 12.0)))
        pts.append((w.chainage + 12.0, after))
    pts.append((spec["length"], min(spec["bed_down"], pts[-1][1])))
    return pts


def zw_profile(p: dict) -> tuple[list[float], list[float], list[float]]:
    """Heights above the bed (m), flow widths (m) and storage widths (m) of a profile."""
    top = p["b"] + 2 * p["m"] * p["hb"]
    heights = [0.0, p["hb"], p["hb"] + 0.3, p["hb"] + 3.0]  # bank at hb, then the floodplain
    flow = [p["b"], top, top + 2 * p["fp_flow"], top + 2 * p["fp_flow"] + 2.0]
    store = [p["b"], top, top + 2 * p["fp_store"], top + 2 * p["fp_store"] + 4.0]
    return heights, flow, store


def along(stream: str, chainage: float) -> tuple[float, float]:
    """Map position (m) of a stream chainage on the layout polyline."""
    pts = np.asarray(LAYOUT[stream])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    t = chainage / STREAMS[stream]["length"] * s[-1]
    return float(np.interp(t, s, pts[:, 0])), float(np.interp(t, s, pts[:, 1]))


def branch_of(stream: str, chainage: float) -> tuple[str, float]:
    """The branch that holds a stream chainage and the chainage on that branch (m)."""
    for bid, st, a, b, _, _ in BRANCHES:
        if st == stream and a <= chainage <= b:
            return bid, chainage - a
    raise ValueError(f"{stream} chainage {chainage} is on no branch")


def _fmt(values) -> str:
    return "[" + ", ".join(f"{v:g}" for v in values) + "]"


def case_toml() -> str:
    """The text of case.toml."""
    lines = [
        "# De Dommel-like weir network (generated by scripts/make_dommel_case.py; see README.md).",
        "[case]",
        'name = "dommel"',
        'description = "De Dommel-like weir network north of Tilburg/Oisterwijk (thesis ch. 4), KNMI 2010 weather"',
        'start = "2010-09-01T00:00:00Z"',
        'end = "2010-12-01T00:00:00Z"',
        "",
        "[engine]",
        "dt = 60.0",
        "output_interval = 3600.0",
        "",
        "[initial]",
        "depth = 0.3",
        "spinup = 96.0",
        "",
        "[friction]",
        'type = "strickler"',
        "value = 16.0",
        "",
        "# KNMI daily weather at Eindhoven (station 370), the station the thesis used; see meteo/ATTRIBUTION.md",
        "[meteo]",
        'file = "meteo/etmgeg_370_20100901-20101201.txt"',
        'format = "knmi-daily"',
        "latitude = 51.451",
        "longitude = 5.377",
        "",
        "# rainfall-runoff model (rivercal.hydrology, WALRUS-type): the a-priori defaults for sandy Brabant soils",
        "[runoff]",
        "",
    ]
    for pid, p in PROFILES.items():
        h, f, s = zw_profile(p)
        lines += ["[[profiles]]", f'id = "{pid}"', 'type = "zw"', f"heights = {_fmt(h)}",
                  f"flow_widths = {_fmt(f)}", f"total_widths = {_fmt(s)}", f"height = {p['hb']:g}  # bank", ""]
    for nid, (stream, ch) in NODES.items():
        x, y = along(stream, ch)
        lines += ["[[nodes]]", f'id = "{nid}"', f"x = {x:.1f}", f"y = {y:.1f}", ""]
    beds = {s: stream_bed(s) for s in STREAMS}
    for bid, stream, a, b, fr, to in BRANCHES:
        pts = [(ch, z) for ch, z in beds[stream] if a < ch < b]
        z_a = float(np.interp(a, *zip(*beds[stream], strict=True)))
        z_b = float(np.interp(b, *zip(*beds[stream], strict=True)))
        prof = [pid for ch0, pid in STREAMS[stream]["profiles"] if ch0 <= a][-1]
        lines += ["[[branches]]", f'id = "{bid}"', f'from_node = "{fr}"', f'to_node = "{to}"',
                  f"length = {b - a:.1f}", "dx = 80.0"]
        geometry = [along(stream, a + (b - a) * k / 12) for k in range(13)]
        lines += ["geometry = [" + ", ".join(f"[{x:.1f}, {y:.1f}]" for x, y in geometry) + "]"]
        lines += ["cross_sections = ["]
        for ch, z in [(a, z_a), *pts, (b, z_b)]:
            lines.append(f'  {{ chainage = {ch - a:.1f}, profile = "{prof}", bed_level = {z:.3f} }},')
        lines += ["]", ""]
    for w in WEIRS:
        bid, ch = branch_of(w.stream, w.chainage)
        comment = f"  # {w.name}" if w.name else f"  # station {next(k for k, v in STATIONS.items() if v == w.id)}"
        lines += ["[[weirs]]" + comment, f'id = "{w.id}"', f'branch = "{bid}"', f"chainage = {ch:.1f}",
                  f"crest_level = {w.crest}", f"crest_width = {w.width}", "discharge_coefficient = 1.0",
                  "lateral_contraction = 0.9", ""]
    for cid, area, where in CATCHMENTS:
        lines += ["[[catchments]]", f'id = "{cid}"', f"area = {area:g}  # ha", ""]
        if where[0] == "boundary":
            lines += ["[[boundaries]]", f'id = "Q_{where[1]}"', f'node = "{where[1]}"', 'type = "discharge"',
                      f'catchment = "{cid}"', ""]
        else:
            bid, ch = branch_of(*where)
            lines += ["[[laterals]]", f'id = "L_{cid}"', f'branch = "{bid}"', f"chainage = {ch:.1f}",
                      f'catchment = "{cid}"', ""]
    # downstream: Q(h) of the receiving water below ZL1 (a broad weir-like control, our choice)
    levels = [3.60, 3.80, 4.00, 4.30, 4.60, 5.00, 5.50, 6.50]
    q = [0.0] + [round(22.0 * (h - 3.60) ** 1.5, 3) for h in levels[1:]]
    lines += ["[[boundaries]]", 'id = "ZL1_outflow"', 'node = "ZL1_out"', 'type = "rating"',
              f"rating = {{ levels = {_fmt(levels)}, discharges = {_fmt(q)} }}", ""]
    for sid, wid in STATIONS.items():
        qty = '["h_up", "h_down", "Q"]' if sid == "0029" else '["h_up", "h_down"]'
        lines += ["[[stations]]", f'id = "{sid}"', f'structure = "{wid}"', f"quantities = {qty}", ""]
    lines += calibration_toml()
    return "\n".join(lines)


def calibration_toml() -> list[str]:
    """Calibration parameters (thesis §4-2-1, §4-4), DuD stopping criteria (Table 4-3), windows (Fig. 4-3)."""
    lines = [
        "# ---- calibration ------------------------------------------------------------------------------",
        "# FA: global Strickler k_s (thesis FA); F1: the ZL1 section just downstream of ZL1-3014 (F1W0 suite)",
        "[[parameters]]", 'name = "FA"', 'targets = ["friction:global"]', "min = 8.0", "max = 40.0",
        "initial = 16.0", 'transform = "offset"', "perturbation = 1.5", 'unit = "m^(1/3)/s"', "",
        "[[parameters]]", 'name = "F1"', 'targets = ["friction:branch:ZL1_3030_3990"]', "min = 8.0", "max = 40.0",
        "initial = 16.0", 'transform = "offset"', "perturbation = 1.5", 'unit = "m^(1/3)/s"', "",
        "# FL: the section Nriv_ZL_1_9820 with W3 and W4, whose friction scenario PI-Fl changes (thesis §5-2-3)",
        "[[parameters]]", 'name = "FL"', 'targets = ["friction:branch:Nriv_ZL_1_9820"]', "min = 8.0", "max = 40.0",
        "initial = 16.0", 'transform = "offset"', "perturbation = 1.5", 'unit = "m^(1/3)/s"', "",
    ]
    adjustable = [w for w in WEIRS if w.name]
    for w in adjustable:
        lines += ["[[parameters]]", f'name = "{w.name}"', f'targets = ["weir:{w.id}.crest_level"]',
                  f"min = {w.zmin}", f"max = {w.zmax}", f"initial = {w.crest}", 'transform = "offset"',
                  "perturbation = 0.1", 'unit = "m AD"', ""]
    lines += ["# Wc: all nine crests at the same fraction of their Table 4-2 range (thesis §4-4)",
              "[[parameters]]", 'name = "Wc"', "min = 0.0", "max = 1.0", "initial = 0.5", 'transform = "offset"',
              "perturbation = 0.1", 'unit = "-"', "cluster = ["]
    for w in adjustable:
        lines.append(f'  {{ target = "weir:{w.id}.crest_level", min = {w.zmin}, max = {w.zmax} }},')
    lines += ["]", "",
              "# Wd: all nine crests moved alike from their DSS settings (m; -0.15 = lowered by 15 cm, thesis §5-2-1);",
              "# the on-line service estimates FA and Wd, whose zero is the DSS",
              "[[parameters]]", 'name = "Wd"', "min = -0.3", "max = 0.3", "initial = 0.0", 'transform = "offset"',
              "perturbation = 0.05", 'unit = "m"', 'cluster_mode = "shift"', "cluster = ["]
    for w in adjustable:
        lines.append(f'  {{ target = "weir:{w.id}.crest_level", min = {w.zmin}, max = {w.zmax}, base = {w.crest} }},')
    lines += ["]", "",
              "# DuD stopping criteria of thesis Table 4-3",
              "[calibration]", 'algorithm = "dud"',
              "options = { max_outer = 20, max_inner = 5, abs_tol = 0.001, rel_tol = 0.0001, "
              "rel_tol_linear = 0.0001, max_rel_step = 10.0 }", "",
              "# the calibration windows of thesis Fig. 4-3",
              "[[windows]]", 'name = "moderate"', 'start = "2010-09-27T00:00:00Z"', 'end = "2010-10-04T00:00:00Z"',
              'description = "moderate rain: the week ending 4 October 2010"', "",
              "[[windows]]", 'name = "extreme"', 'start = "2010-11-08T00:00:00Z"', 'end = "2010-11-15T00:00:00Z"',
              'description = "extreme rain: 8-15 November 2010"', ""]
    return lines


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "case.toml").write_text(case_toml(), encoding="utf-8")
    total = sum(a for _, a, _ in CATCHMENTS)
    print(f"wrote {OUT}: {len(WEIRS)} weirs, {len(CATCHMENTS)} catchments, {total / 100:.0f} km²")


if __name__ == "__main__":
    main()
