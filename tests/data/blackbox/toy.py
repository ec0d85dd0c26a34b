"""A toy external model for the black-box tests: a reservoir level relaxing to a rating of a known inflow.

Reads ``input.json`` (rendered from a template: k, crest, run_start, end, hot), writes ``out.csv`` (hourly
levels ``h`` and discharges ``q``; a hot start omits its first row, as SWMM does) and ``restart.txt``
(the level at the end); ``restart_in.txt`` holds the level of a hot start. ``TOY_MODE`` in the
environment makes it misbehave: ``fail`` (exit 3), ``hang`` (sleeps, with a child that sleeps too),
``nan``, ``nothing``, ``truncated`` (half the rows), ``argv`` (writes its arguments to argv.json),
``escape`` (hangs, with a grandchild that starts a session of its own and a child in its process group),
``background`` (the same helpers, but the run itself succeeds and leaves them running), ``text`` (a value
that is text), ``duplicate`` (a time written twice), ``fifo`` (out.csv is a FIFO), ``link`` (out.csv is a
link to a file outside the run folder, named by ``TOY_LINK``), ``selfkill`` (ends by SIGKILL);
``TOY_FAIL_ABOVE`` makes it exit 4 for a larger k; ``TOY_DAEMON=1`` makes every run leave ``sleep 120``
running in a session of its own (as a daemon would). The helpers write their pids, one a line, to
``pids.txt`` (the program's own first) once they all run.
"""

import json
import math
import os
import subprocess
import sys
import time
from datetime import datetime, timedelta

mode = os.environ.get("TOY_MODE", "")
if os.environ.get("TOY_DAEMON") == "1":
    subprocess.Popen(["sleep", "120"], start_new_session=True, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                     stderr=subprocess.DEVNULL)
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
if mode in ("escape", "background"):
    # a helper in the program's process group, and a grandchild that leaves the group (a session of its own)
    helper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)"])
    leaver = "import os, time; os.setsid(); print(os.getpid(), flush=True); time.sleep(120)"
    escaper = subprocess.Popen([sys.executable, "-c", "import subprocess, sys, time\n"
                                f"p = subprocess.Popen([sys.executable, '-c', {leaver!r}], stdout=subprocess.PIPE)\n"
                                "sys.stdout.write(p.stdout.readline().decode()); sys.stdout.flush()\n"
                                "time.sleep(120)"], stdout=subprocess.PIPE, text=True)
    grandchild = int(escaper.stdout.readline())
    with open("pids.tmp", "w") as f:
        f.write(f"{os.getpid()}\n{helper.pid}\n{escaper.pid}\n{grandchild}\n")
    os.replace("pids.tmp", "pids.txt")
    if mode == "escape":
        time.sleep(120)
if mode == "fifo":
    os.mkfifo("out.csv")
    sys.exit(0)
if mode == "link":
    os.symlink(os.environ["TOY_LINK"], "out.csv")
    sys.exit(0)
if mode == "selfkill":
    os.kill(os.getpid(), 9)

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
        middle = t == rows[len(rows) // 2][0]
        value = {"nan": "nan", "text": "high"}.get(mode, f"{zz:.9f}") if middle else f"{zz:.9f}"
        f.write(f"{t.isoformat()},{value},{q:.9f}\n")
        if mode == "duplicate" and middle:
            f.write(f"{t.isoformat()},{zz + 1:.9f},{q:.9f}\n")
with open("restart.txt", "w") as f:
    f.write(repr(z))
