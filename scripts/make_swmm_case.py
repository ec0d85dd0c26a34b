"""Generate the packaged ``dommel-swmm`` case: the default case's network and forcing as an EPA SWMM 5 model.

The network of ``dommel`` (its weirs, stations and the rainfall-runoff inflows of its catchments, computed
once by rivercal's hydrology from the KNMI 2010 weather) is written as ``dommel.inp`` by
:func:`rivercal.models.swmm.convert.case_to_inp` (500 m conduits, 30 s routing steps with SWMM's conduit
lengthening at that step, 96 h spin-up), and
``model.toml`` names the stations and the calibration parameters: ``FR`` (a factor on every conduit's
Manning n) and every parameter of ``dommel`` on the same quantities (FA, F1, FL: Strickler k_s, which
SWMM takes as n = 1/k_s; W1 … W9, Wc, Wd: crests).

Run from the repository root: ``python scripts/make_swmm_case.py``.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from rivercal.models import load_model
from rivercal.models.swmm.convert import case_to_inp

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src" / "rivercal" / "cases" / "dommel-swmm"
START, END = pd.Timestamp("2010-09-20", tz="UTC"), pd.Timestamp("2010-11-20", tz="UTC")
SPINUP_H = 96.0


def _value(v) -> str:
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return f"{v:g}" if isinstance(v, float) else str(v)


def _parameter_toml(p) -> str:
    """One ``[[parameters]]`` table of a Parameter (clusters as inline tables, one per line)."""
    data = p.model_dump(exclude_defaults=True)
    lines = ["[[parameters]]"]
    for key, value in data.items():
        if key == "cluster":
            members = ",\n".join("  { " + ", ".join(f"{k} = {_value(v)}" for k, v in c.items() if v is not None)
                                  + " }" for c in value)
            lines.append(f"cluster = [\n{members},\n]")
        else:
            lines.append(f"{key} = {_value(value)}")
    return "\n".join(lines) + "\n"


def main() -> None:
    dommel = load_model("dommel")
    # SWMM's own remedy for the short conduits beside weirs near a branch end: lengthen them to their
    # Courant length at the routing step (without it the 13 November flood blows up at 30 s steps)
    export = case_to_inp(dommel.case, dommel.forcing, dx=500.0, routing_step=30.0, lengthening_step=30.0,
                         spinup=SPINUP_H, start=START, end=END,
                         title="De Dommel-like weir network (rivercal case dommel) as an EPA SWMM 5 model")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "dommel.inp").write_text(export.text, encoding="utf-8")
    stations = "\n".join(f'"{k}" = "{v}"' for k, v in export.stations.items())
    parameters = "\n".join(_parameter_toml(p) for p in dommel.calibration.parameters)
    options = ", ".join(f"{k} = {v!r}" for k, v in dommel.calibration.options.items())
    windows = "\n".join(f'[[windows]]\nname = "{n}"\nstart = "{a.isoformat()}"\nend = "{b.isoformat()}"\n'
                        for n, (a, b) in dommel.calibration.windows.items())
    text = f'''# The default case's network as an EPA SWMM 5 model (scripts/make_swmm_case.py; see README.md).
[model]
name = "dommel-swmm"
kind = "swmm"
description = "De Dommel-like weir network (case dommel) in EPA SWMM 5: same weirs, stations and inflows"
start = "{START.isoformat()}"
end = "{END.isoformat()}"
output_interval = 3600.0
spinup = {SPINUP_H:g}

[swmm]
inp = "dommel.inp"

[swmm.stations]
{stations}

# FR: a factor on the Manning n of every conduit (1 = n 1/16 s/m^(1/3), the case's k_s = 16)
[[parameters]]
name = "FR"
targets = ["roughness:factor"]
min = 0.3
max = 3.0
initial = 1.0
transform = "factor"
perturbation = 0.1
unit = "-"

# the parameters of dommel, on the same quantities (SWMM: k_s as n = 1/k_s; crests in m AD)
{parameters}
[calibration]
algorithm = "dud"
options = {{ {options} }}

{windows}'''
    (OUT / "model.toml").write_text(text, encoding="utf-8")
    print(f"wrote {OUT}: {export.junctions} junctions, {export.conduits} conduits, {len(export.weirs)} weirs")


if __name__ == "__main__":
    main()
