"""Dashboard page load on a store with a year of daily cycles: server time + browser render, in the browser.

Builds a store of 365 synthetic daily cycles through the store API (11 series, forecasts 48 h ahead
hourly for the updated model and the DSS, hourly observations, scores), serves it with
``rivercal dashboard`` on 127.0.0.1, and loads every page in headless chromium (Debian's, through
chromedriver). A page's load time is from the start of the navigation to the moment the page's script
has drawn every figure (``window.rivercalReady``, ms since the navigation started). The first load
of each page (empty browser cache: plotly.js is compiled) is reported apart; the target is the median
of the following loads. Prints one JSON line.

Usage: ``python benchmarks/dashboard_load.py [--cycles 365] [--repeat 7]`` (``make bench`` runs it).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.dashboard_store import build_store  # noqa: E402
from tests.e2e.browser import chrome, start_dashboard  # noqa: E402

PAGES = ("/", "/estimates", "/forecasts", "/map", "/cycles")
TARGET_MS = 1000.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cycles", type=int, default=365)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        db = build_store(Path(tmp) / "run.sqlite", args.cycles)
        build_s = time.perf_counter() - t
        proc, url = start_dashboard(db)
        driver = chrome(Path(tmp) / "profile")
        pages = {}
        try:
            for page in PAGES:
                loads = []
                for _ in range(args.repeat + 1):
                    driver.get(url + page)
                    deadline = time.monotonic() + 60
                    while not driver.execute_script("return document.body.dataset.ready === '1'"):
                        if time.monotonic() > deadline:
                            raise RuntimeError(f"{page} was not drawn within a minute")
                        time.sleep(0.01)
                    loads.append(float(driver.execute_script("return window.rivercalReady")))
                pages[page] = {"first_ms": round(loads[0], 1), "median_ms": round(statistics.median(loads[1:]), 1),
                               "max_ms": round(max(loads[1:]), 1), "runs": len(loads) - 1}
        finally:
            driver.quit()
            proc.terminate()
            proc.wait(timeout=30)
    worst = max(p["median_ms"] for p in pages.values())
    print(json.dumps({"benchmark": "dashboard", "cycles": args.cycles, "store_build_s": round(build_s, 1),
                      "pages": pages, "worst_median_ms": worst, "target_ms": TARGET_MS, "met": worst <= TARGET_MS}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
