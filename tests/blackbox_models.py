"""The toy black-box model of tests/data/blackbox/toy.py as a model folder (shared by the black-box tests)."""

from __future__ import annotations

import json
import shutil
import textwrap
from pathlib import Path

import pandas as pd

from rivercal.models import load_model
from rivercal.models.blackbox import BlackBoxModel

TOY = Path(__file__).resolve().parents[0] / "data" / "blackbox" / "toy.py"
START = pd.Timestamp("2020-01-01", tz="UTC")
TEMPLATE = '{"k": {{k:.12g}}, "crest": {{crest}}, "run_start": "{{run_start}}", "end": "{{end}}", "hot": {{hot}}}\n'


def make_model(tmp_path: Path, *, mode: str = "", timeout: float = 30.0, extra_argv: tuple[str, ...] = (),
               runs_dir: str | None = None, keep_failed: int = 5, spinup: float = 0.0,
               outputs: str | None = None) -> BlackBoxModel:
    folder = tmp_path / "toy"
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copy(TOY, folder / "toy.py")
    (folder / "input.json.tmpl").write_text(TEMPLATE)
    argv = json.dumps(["{python}", "toy.py", *extra_argv])
    outputs = outputs or '''[[blackbox.outputs]]
reader = "csv"
file = "out.csv"
series = { "S.h" = "level", "S.Q" = "flow" }'''
    (tmp_path / "model.toml").write_text(textwrap.dedent(f'''\
        [model]
        name = "toy"
        kind = "blackbox"
        start = "2020-01-01T00:00:00Z"
        end = "2020-01-20T00:00:00Z"
        dt = 3600
        output_interval = 3600
        spinup = {spinup}

        [blackbox]
        folder = "toy"
        command = {argv}
        env = {{ TOY_MODE = "{mode}" }}
        timeout = {timeout}
        keep_failed = {keep_failed}
        {f'runs_dir = "{runs_dir}"' if runs_dir else ''}
        templates = [{{ source = "input.json.tmpl" }}]
        state = {{ restart_out = ["restart.txt"], restart_in = ["restart_in.txt"] }}

        [blackbox.quantities.k]
        unit = "m^3/s"
        min = 0.5
        max = 20.0
        default = 3.0

        [blackbox.quantities.crest]
        unit = "m"
        default = 10.0
        format = ".6f"
        ''') + outputs + "\n")
    return load_model(tmp_path / "model.toml")
