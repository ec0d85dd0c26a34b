"""A real headless browser for the dashboard tests: Debian's chromium driven by selenium through chromedriver.

``make test`` installs ``chromium`` and ``chromium-driver`` with apt-get when they are missing; the tests
fail (never skip) when they are not there. Nothing is downloaded at run time: the driver and the browser
are given by path, so selenium's own driver manager is never asked.
"""

from __future__ import annotations

import http.client
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

CHROMIUM = os.environ.get("RIVERCAL_CHROMIUM", "/usr/bin/chromium")
CHROMEDRIVER = os.environ.get("RIVERCAL_CHROMEDRIVER", "/usr/bin/chromedriver")
FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--disable-extensions",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run",
         "--disable-default-apps", "--metrics-recording-only", "--window-size=1280,1000")


def chrome(user_data: Path):
    """A headless chromium with a fresh profile in ``user_data``; browser console logs are kept."""
    for path, package in ((CHROMIUM, "chromium"), (CHROMEDRIVER, "chromium-driver")):
        if not Path(path).exists() and not shutil.which(path):
            pytest.fail(f"{path} is missing: install Debian's {package} (make test does: apt-get install chromium "
                        "chromium-driver)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={user_data}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    return webdriver.Chrome(options=options, service=Service(executable_path=CHROMEDRIVER))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def start_dashboard(db: Path, *, poll: float = 0.5, timeout: float = 60.0) -> tuple[subprocess.Popen, str]:
    """``rivercal dashboard --db DB`` on a free port of 127.0.0.1; returns the process and the base URL."""
    port = free_port()
    proc = subprocess.Popen([sys.executable, "-m", "rivercal.cli", "dashboard", "--db", str(db), "--port", str(port),
                             "--poll", str(poll)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise AssertionError(f"the dashboard exited with {proc.returncode}: {proc.stderr.read()}")
        try:
            status, _, _ = request("127.0.0.1", port, "GET", "/api/version")
            if status == 200:
                return proc, f"http://127.0.0.1:{port}"
        except OSError:
            time.sleep(0.1)
    proc.kill()
    raise AssertionError("the dashboard did not answer within a minute")


def request(host: str, port: int, method: str, path: str, body: bytes | None = None) -> tuple[int, dict, bytes]:
    """One raw HTTP request (the path is sent as it is, unnormalised); returns status, headers, body."""
    conn = http.client.HTTPConnection(host, port, timeout=10)
    try:
        conn.request(method, path, body=body)
        response = conn.getresponse()
        return response.status, {k.lower(): v for k, v in response.getheaders()}, response.read()
    finally:
        conn.close()
