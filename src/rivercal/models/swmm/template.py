"""A black-box template of a SWMM input file: SWMM driven as an external program.

:func:`inp_template` turns an ``.inp`` file into a template for :mod:`rivercal.models.blackbox`: the run's
dates and reporting step, a roughness factor on every conduit's Manning n (``{{FR*n}}``), a shift of
chosen weirs' crest heights (``{{Wd+h}}``), SWMM's hotstart files (``{{hot:USE HOTSTART …}}``) and a
``[REPORT]`` of the stations. With :func:`blackbox_files` it writes a complete black-box model folder
whose program is SWMM's command-line runner (:mod:`rivercal.models.swmm.runner`).
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Mapping
from pathlib import Path

from rivercal.models.swmm.inp import InpFile, seconds, swmm_step
from rivercal.models.swmm.output import parse_element

__all__ = ["blackbox_files", "inp_template"]


def inp_template(inp: InpFile, stations: Mapping[str, str], *, roughness: str | None = "FR",
                 crest_shift: str | None = "Wd", weirs: Iterable[str] = (), report_step: float = 3600.0) -> str:
    """The template text of ``inp`` (module docstring).

    Parameters
    ----------
    inp
        The SWMM input file.
    stations
        ``<station>.<quantity>`` → ``node:<id>`` / ``link:<id>`` (written into ``[REPORT]``).
    roughness
        Quantity that multiplies every conduit's Manning n (None: roughness stays).
    crest_shift
        Quantity added to the crest height of the ``weirs`` (m; None: crests stay).
    weirs
        Weir ids that the crest shift moves.
    report_step
        SWMM's reporting step, s (the black box's ``output_interval``).

    Raises
    ------
    KeyError
        For a weir the file does not have.
    """
    t = inp.copy()
    for key, value in (("START_DATE", "{{run_start:%m/%d/%Y}}"), ("START_TIME", "{{run_start:%H:%M:%S}}"),
                       ("REPORT_START_DATE", "{{run_start:%m/%d/%Y}}"),
                       ("REPORT_START_TIME", "{{run_start:%H:%M:%S}}"), ("END_DATE", "{{end:%m/%d/%Y}}"),
                       ("END_TIME", "{{end:%H:%M:%S}}"), ("REPORT_STEP", swmm_step(report_step))):
        t.set_option(key, value)
    if roughness is not None:
        for row in t.rows("CONDUITS"):
            row.tokens[4] = f"{{{{{roughness}*{float(row.tokens[4]):.12g}:.10g}}}}"
    if crest_shift is not None:
        table = t.table("WEIRS")
        for w in weirs:
            if w not in table:
                raise KeyError(f"{inp.source}: [WEIRS] has no weir {w!r}")
            table[w].tokens[4] = f"{{{{{crest_shift}+{float(table[w].tokens[4]):.12g}:.10g}}}}"
    t.replace_section("FILES", ['{{hot:USE HOTSTART "restart_in.hsf"}}', 'SAVE HOTSTART "restart_out.hsf"'])
    nodes = sorted({parse_element(s)[1] for s in stations.values() if s.startswith("node:")})
    links = sorted({parse_element(s)[1] for s in stations.values() if s.startswith("link:")})
    t.replace_section("REPORT", ["INPUT NO", "CONTROLS NO", "SUBCATCHMENTS NONE",
                                 f"NODES {' '.join(nodes)}" if nodes else "NODES NONE",
                                 f"LINKS {' '.join(links)}" if links else "LINKS NONE"])
    return t.text()


def blackbox_files(folder: str | Path, inp: str | Path, stations: Mapping[str, str], *, name: str, start: str,
                   end: str, spinup: float, weirs: Iterable[str], timeout: float = 600.0,
                   extra_toml: str = "") -> Path:
    """Write a black-box model folder that runs SWMM on a template of ``inp``; return its ``model.toml``.

    The folder holds ``model.toml`` and ``model/model.inp.tmpl``; quantities ``FR`` (factor on every
    conduit's Manning n) and ``Wd`` (crest shift of ``weirs``, m); outputs the SWMM binary output;
    state SWMM's hotstart file. ``extra_toml`` is appended (e.g. ``[[parameters]]``).
    """
    folder = Path(folder)
    src = InpFile.read(inp)
    weirs = list(weirs)
    (folder / "model").mkdir(parents=True, exist_ok=True)
    (folder / "model" / "model.inp.tmpl").write_text(inp_template(src, stations, weirs=weirs), encoding="utf-8")
    dt = seconds(src.option("ROUTING_STEP"), 20.0)
    series = ", ".join(f"{json.dumps(k)} = {json.dumps(v)}" for k, v in stations.items())
    text = f'''[model]
name = "{name}"
kind = "blackbox"
start = "{start}"
end = "{end}"
dt = {dt:g}
output_interval = 3600
spinup = {spinup:g}

[blackbox]
folder = "model"
command = ["{{python}}", "-m", "rivercal.models.swmm.runner", "model.inp", "model.rpt", "model.out"]
timeout = {timeout:g}
templates = [{{ source = "model.inp.tmpl" }}]
state = {{ restart_out = ["restart_out.hsf"], restart_in = ["restart_in.hsf"] }}

[blackbox.quantities.FR]
unit = "-"
min = 0.01
max = 100.0
default = 1.0
description = "factor on the Manning n of every conduit"

[blackbox.quantities.Wd]
unit = "m"
min = -5.0
max = 5.0
default = 0.0
description = "crest shift of {len(weirs)} weirs"

[[blackbox.outputs]]
reader = "swmm"
file = "model.out"
series = {{ {series} }}
{extra_toml}'''
    (folder / "model.toml").write_text(text, encoding="utf-8")
    return folder / "model.toml"
