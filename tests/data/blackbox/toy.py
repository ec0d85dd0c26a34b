"""A toy external model for the black-box tests: a reservoir level relaxing to a rating of a known inflow.

Reads ``input.json`` (rendered from a template: k, crest, run_start, end, hot), writes ``out.csv`` (hourly
levels ``h`` and discharges ``q``; a hot start omits its first row, as SWMM does) and ``restart.txt``
(the level at the end); ``restart_in.txt`` holds the level of a hot start. ``TOY_MODE`` in the
environment makes it misbehave: ``fail`` (exit 3), ``hang`` (sleeps, with a child that sleeps too),
``nan``, ``nothing``, ``truncated`` (half the rows), ``argv`` (writes its arguments to argv.json);
``TOY_FAIL_ABOVE`` makes it exit 4 for a larger k.
"""

import json
import math
import os
import subprocess
import sys
import time
from datetime import datetime, timedelta

mode = os.environ.get("TOY_MODE", "")
if mode == "argv":
    with open("argv.json", "w") as f:
        json.dump(sys.argv[1:], f)
if mode == "fail":
    sys.stderr.write("toy: the input makes no sense\n")
    sys.exit(3)
if mode == "hang":
    with open("child.pid", "w") as f:
        f.write(str(subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"]).pid))
    time.sleep(60)
if mode == "nothing":
    sys.exit(0)

with open("input.json") as f:
    p = json.load(f)
k, crest = p["k"], p["crest"]
if k > float(os.environ.get("TOY_FAIL_ABOVE", "inf")):
    sys.stderr.write(f"toy: k = {k} is too large\n")
    sys.exit(4)
t0 = datetime.fromisoformat(p["run_start"])
t1 = datetime.fromisoformat(p["end"])
hot = p["hot"] == 1
z = float(open("restart_in.txt").read()) if hot else crest + 0.5
epoch = datetime.fromisoformat("2020-01-01T00:00:00+00:00")
rows = []
t = t0
while True:
    days = (t - epoch).total_seconds() / 86400.0
    q = 2.0 + math.sin(2 * math.pi * days / 5.0)
    if t > t0:
        target = crest + (q / k) ** 0.6
        z = z + (target - z) * (1.0 - math.exp(-1.0 / 3.0))
    if not (hot and t == t0):
        rows.append((t, z, q))
    if t >= t1:
        break
    t += timedelta(hours=1)
if mode == "truncated":
    rows = rows[: len(rows) // 2]
with open("out.csv", "w") as f:
    f.write("time,level,flow\n")
    for t, zz, q in rows:
        value = "nan" if mode == "nan" and t == rows[len(rows) // 2][0] else f"{zz:.9f}"
        f.write(f"{t.isoformat()},{value},{q:.9f}\n")
with open("restart.txt", "w") as f:
    f.write(repr(z))
