"""A stand-in for an external model: a linear reservoir behind a weir, hourly.

Reads the settings file rivercal rendered (period, crest level in m AD, outflow rate k in 1/h) and the
inflow series, and writes the level (m AD) and the outflow (m³/s) per hour as CSV. Usage:
``python reservoir.py settings.txt output.csv``.
"""

import csv
import sys
from datetime import UTC, datetime, timedelta

AREA = 20_000.0  # m², the reservoir's surface


def read_settings(path):
    values = {}
    for line in open(path, encoding="utf-8"):
        if "=" in line and not line.startswith("#"):
            key, value = (part.strip() for part in line.split("=", 1))
            values[key] = value
    return values


def inflow(t):
    """m³/s: a base flow and a flood wave on 4 March."""
    hours = (t - datetime(2021, 3, 1, tzinfo=UTC)).total_seconds() / 3600.0
    return 0.5 + 1.5 * max(0.0, 1.0 - abs(hours - 80.0) / 24.0)


def main(settings_file, output_file):
    s = read_settings(settings_file)
    start = datetime.fromisoformat(s["start"])
    end = datetime.fromisoformat(s["end"])
    crest, k = float(s["crest"]), float(s["k"])
    storage = 0.0  # m³ above the crest
    t = start
    with open(output_file, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        out.writerow(["time", "level", "outflow"])
        while t <= end:
            outflow = k / 3600.0 * storage
            out.writerow([t.strftime("%Y-%m-%dT%H:%M:%SZ"), f"{crest + storage / AREA:.6f}", f"{outflow:.6f}"])
            storage += 3600.0 * (inflow(t) - outflow)
            t += timedelta(hours=1)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
