"""The black box's own overhead per run, beside the external program's time (``rivercal bench blackbox``).

The external program is trivial: ``cp`` copies a prepared CSV (one day of hourly levels at three
stations) to the output file, so nearly all of a run is the black box itself: making the run folder (the
model folder copied), rendering a template, starting the program, reading and checking its output,
keeping its restart file and removing the folder. The same ``cp`` is also timed alone (started the same
way, in a prepared folder), interleaved with the black-box runs; the overhead is the difference of the
medians.
"""

from __future__ import annotations

import statistics
import subprocess
import tempfile
import textwrap
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from rivercal.models.load import load_model_file

__all__ = ["BlackBoxBenchmark", "bench_blackbox"]


@dataclass(frozen=True)
class BlackBoxBenchmark:
    """Result of :func:`bench_blackbox` (times in ms, medians)."""

    runs: int
    program_ms: float
    blackbox_ms: float
    overhead_ms: float

    def to_dict(self) -> dict:
        """Plain-dict form for JSON."""
        return asdict(self)


def _model(folder: Path) -> Path:
    model = folder / "model"
    model.mkdir(parents=True)
    times = pd.date_range("2020-01-01", "2020-01-02", freq="h", tz="UTC")
    frame = pd.DataFrame({"time": times.strftime("%Y-%m-%dT%H:%M:%SZ"), **{f"h{i}": 10.0 + np.sin(np.arange(25) / 4 + i)
                                                                         for i in range(3)}})
    frame.to_csv(model / "result.csv", index=False)
    (model / "restart.txt").write_text("1.0\n")
    (model / "params.txt.tmpl").write_text("k = {{k:.6f}}\nstart = {{start:%Y-%m-%d %H:%M}}\nend = {{end}}\n")
    (folder / "model.toml").write_text(textwrap.dedent('''\
        [model]
        name = "trivial"
        kind = "blackbox"
        start = "2020-01-01T00:00:00Z"
        end = "2020-01-02T00:00:00Z"
        dt = 3600
        output_interval = 3600

        [blackbox]
        folder = "model"
        command = ["cp", "result.csv", "out.csv"]
        templates = [{ source = "params.txt.tmpl" }]
        state = { restart_out = ["restart.txt"], restart_in = ["restart_in.txt"] }
        runs_dir = "runs"

        [blackbox.quantities.k]
        default = 1.0

        [[blackbox.outputs]]
        reader = "csv"
        file = "out.csv"
        series = { "A.h" = "h0", "B.h" = "h1", "C.h" = "h2" }
        '''))
    return folder / "model.toml"


def bench_blackbox(runs: int = 40) -> BlackBoxBenchmark:
    """Median time of a black-box run with a trivial program, of the program alone, and their difference."""
    with tempfile.TemporaryDirectory() as tmp:
        box = load_model_file(_model(Path(tmp)))
        alone = Path(tmp) / "alone"
        alone.mkdir()
        (alone / "result.csv").write_bytes((Path(tmp) / "model" / "result.csv").read_bytes())
        box.simulate({"k": 1.0})  # warm up imports and caches
        total, program = [], []
        for i in range(runs):
            t0 = time.perf_counter()
            subprocess.run(["cp", "result.csv", "out.csv"], cwd=alone, stdin=subprocess.DEVNULL,
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, start_new_session=True)
            program.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            box.simulate({"k": 1.0 + i / runs})
            total.append(time.perf_counter() - t0)
    p, b = statistics.median(program) * 1e3, statistics.median(total) * 1e3
    return BlackBoxBenchmark(runs=runs, program_ms=round(p, 2), blackbox_ms=round(b, 2), overhead_ms=round(b - p, 2))
