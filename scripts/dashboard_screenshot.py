"""Take the README's dashboard screenshot (docs/dashboard.png) in headless chromium.

Usage: ``python scripts/dashboard_screenshot.py [--db run.sqlite] [--page /estimates] [--full]``. The committed
screenshot is of the demo's store, the first screen of the estimates page at 1280×800: ``make demo && python
scripts/dashboard_screenshot.py --db out/demo/run.sqlite``. ``--full`` takes the whole page. Without ``--db`` a
store of 30 synthetic daily cycles is built (tests/dashboard_store.py), for a quick look.
"""

from __future__ import annotations

import argparse
import base64
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.dashboard_store import build_store  # noqa: E402
from tests.e2e.browser import chrome, start_dashboard  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--db", type=Path)
    parser.add_argument("--page", default="/estimates")
    parser.add_argument("--out", type=Path, default=ROOT / "docs" / "dashboard.png")
    parser.add_argument("--full", action="store_true", help="the whole page, not only the first screen")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        db = args.db or build_store(Path(tmp) / "run.sqlite", 30)
        proc, url = start_dashboard(db)
        driver = chrome(Path(tmp) / "profile")
        try:
            driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                                   {"width": 1280, "height": 800, "deviceScaleFactor": 1, "mobile": False})
            driver.get(url + args.page)
            while not driver.execute_script("return document.body.dataset.ready === '1'"):
                time.sleep(0.05)
            time.sleep(0.5)
            if args.full:
                options = {"format": "png", "captureBeyondViewport": True}
                shot = driver.execute_cdp_cmd("Page.captureScreenshot", options)
                args.out.write_bytes(base64.b64decode(shot["data"]))
            else:
                driver.save_screenshot(str(args.out))
        finally:
            driver.quit()
            proc.terminate()
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
