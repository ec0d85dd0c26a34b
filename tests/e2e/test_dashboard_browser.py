"""The dashboard in a real headless browser: pages load without JavaScript errors, the numbers in the DOM
are the store's, a cycle committed while a page is open appears without a reload, and nothing but reading
is possible (other methods, path traversal, writes)."""

from __future__ import annotations

import hashlib
import time
from pathlib import Path
from urllib.parse import urlparse

import numpy as np
import pandas as pd
import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from rivercal.store import Store
from tests.dashboard_store import add_cycle, build_store
from tests.e2e.browser import chrome, request, start_dashboard

N_CYCLES = 12
PAGES = ("/", "/forecast", "/estimates", "/forecasts", "/map", "/cycles")


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dashboard")
    db = build_store(folder / "run.sqlite", N_CYCLES)
    driver = chrome(folder / "profile")  # first: without a browser no server is left behind
    try:
        proc, url = start_dashboard(db)
    except BaseException:
        driver.quit()
        raise
    try:
        yield db, url, driver
    finally:
        driver.quit()
        proc.terminate()
        proc.wait(timeout=30)


def _open(driver, url: str) -> float:
    """Load a page, wait until its script has drawn it; returns the load time (ms, navigation to drawn)."""
    driver.get(url)
    WebDriverWait(driver, 30).until(lambda d: d.execute_script("return document.body.dataset.ready === '1'"))
    return float(driver.execute_script("return window.rivercalReady"))


def _errors(driver) -> list[str]:
    return [e["message"] for e in driver.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]


def _raw(driver, css: str) -> list[float]:
    return [float(e.get_attribute("data-raw")) if e.get_attribute("data-raw") else np.nan
            for e in driver.find_elements(By.CSS_SELECTOR, css)]


def test_every_page_loads_without_javascript_errors_and_draws(served) -> None:
    _, url, driver = served
    times = {}
    for page in PAGES:
        times[page] = _open(driver, url + page)
        assert _errors(driver) == [], page
        assert driver.title.startswith("rivercal")
        plots = driver.find_elements(By.CSS_SELECTOR, ".plot")
        drawn = driver.find_elements(By.CSS_SELECTOR, ".plot .main-svg")
        assert len(drawn) >= len(plots), f"{page}: {len(plots)} plots, {len(drawn)} drawn"
    assert len(driver.find_elements(By.CSS_SELECTOR, ".plot")) == 0  # the cycle log is a table
    print("page load (ms, navigation to drawn):", {k: round(v) for k, v in times.items()})


def test_the_numbers_on_the_pages_are_the_stores(served) -> None:
    db, url, driver = served
    with Store(db, readonly=True) as store:
        run = store.get_run("dash")
        cycles, est, scores = store.cycles(run), store.estimates(run), store.scores(run)
        fc = store.forecasts(run, series=["0029.Q"])
        accepted_values = store.last_accepted(run)
        issued_fc = store.forecasts(run, cycle=int(cycles["cycle"].max()))
        observed = store.observation_table(["0029.Q"], "2010-01-01", "2010-02-01")
    last = est[est["cycle"] == cycles["cycle"].max()].set_index("parameter")
    latest = cycles.iloc[-1]
    kind = latest["issued_forecast"]
    dss = {"FA": 16.0, "Wd": 0.0}  # the case's own friction and crests, which the DSS keeps
    _open(driver, url + "/")
    for name, row in last.iterrows():
        cells = driver.find_elements(By.CSS_SELECTOR, f'tr[data-parameter="{name}"] td')
        accepted = accepted_values[name]
        # in use: the values behind the forecast the latest cycle issued (the DSS's after a fallback)
        assert float(cells[0].get_attribute("data-raw")) == (dss[name] if kind == "dss" else accepted)
        assert float(cells[1].get_attribute("data-raw")) == accepted
        assert cells[1].text == (f"{accepted:.1f}" if name == "FA" else f"{accepted:.2f}")
        assert float(cells[2].get_attribute("data-raw")) == row["std"]
        assert float(cells[3].get_attribute("data-raw")) == pytest.approx(dss[name], abs=1e-9)
        assert cells[5].text == ("accepted" if row["accepted"] else "held")
    assert driver.find_element(By.CSS_SELECTOR, "div.alert").get_attribute("data-cycle") == "10"
    change = driver.find_element(By.ID, "change")
    assert change.get_attribute("data-parameter") == "FA" and change.get_attribute("data-found") == "10"
    assert "changed from 16.0 to" in change.text and "2010-01-17 06:00" in change.text
    # the forecast the latest cycle issued (the DSS's, as a fallback, unless a cycle was added)
    issued = driver.find_element(By.ID, "issued")
    assert issued.get_attribute("data-kind") == kind
    whose = "the DSS's" if kind == "dss" else "rivercal's"
    assert issued.text.startswith(f"Forecast in use: {whose}, issued {latest['issue_time']:%Y-%m-%d %H:%M} by cycle "
                                  f"{latest['cycle']} — ")
    # the forecast page: 48 h of observations before the issue time, the issued forecast and the other one
    _open(driver, url + "/forecast")
    plot = driver.find_element(By.CSS_SELECTOR, '.plot[data-series="0029.Q"]')
    traces = dict(driver.execute_script("return arguments[0].data.map(t => [t.name, t.y])", plot))
    mine = issued_fc[issued_fc["series"] == "0029.Q"]
    issued_name = "DSS (issued)" if kind == "dss" else "rivercal (issued)"
    other_name = "rivercal (not issued)" if kind == "dss" else "DSS (not issued)"
    assert traces[issued_name] == mine[mine["kind"] == kind]["value"].tolist()
    assert traces[other_name] == mine[mine["kind"] != kind]["value"].tolist()
    t0 = latest["issue_time"]
    obs = observed[(observed["series"] == "0029.Q") & (observed["time"] >= t0 - pd.Timedelta("48h"))
                   & (observed["time"] <= t0)]
    assert traces["observed"] == obs["value"].tolist() and len(obs) == 49
    assert "jump alert" in driver.find_element(By.ID, "events").text  # cycle 10's, within the four days
    # the cycle log: one row per cycle, newest first, model runs and wall time as stored
    _open(driver, url + "/cycles")
    rows = driver.find_elements(By.CSS_SELECTOR, "#cycles tbody tr")
    assert [int(r.get_attribute("data-cycle")) for r in rows] == cycles["cycle"].tolist()[::-1]
    assert _raw(driver, "#cycles tbody tr td:nth-of-type(4)") == cycles["model_runs"].astype(float).tolist()[::-1]
    assert _raw(driver, "#cycles tbody tr td:nth-of-type(5)") == cycles["wall_time_s"].tolist()[::-1]
    # estimates over time: the plotted points are the stored estimates (accepted and held), the DSS's value a line
    _open(driver, url + "/estimates")
    dss = {"FA": 16.0, "Wd": 0.0}
    for plot in driver.find_elements(By.CSS_SELECTOR, ".plot"):
        name = plot.get_attribute("data-parameter")
        traces = dict(driver.execute_script("return arguments[0].data.map(t => [t.name, t.y])", plot))
        ys = traces["rivercal, accepted (±σ)"] + traces.get("held (not used)", [])
        assert sorted(ys) == sorted(est.loc[est["parameter"] == name, "value"].tolist())
        assert traces["DSS"] == pytest.approx([dss[name]] * 2, abs=1e-9)
        marks = driver.execute_script("return arguments[0].layout.annotations.map(a => [a.text, a.x])", plot)
        # FA's jump alert (cycle 10) and the time of its change; the Wd plot has neither
        assert sorted(marks) == ([["jump alert", "2010-01-18 00:00"], ["transition", "2010-01-17 06:00"]]
                                 if name == "FA" else [])
    # forecasts at 12 h ahead against the observations, and the scores per lead time
    _open(driver, url + "/forecasts?run=dash&series=0029.Q&lead=12")
    plot = driver.find_element(By.ID, "forecast-plot")
    traces = driver.execute_script("return arguments[0].data.map(t => [t.name, t.y])", plot)
    at12 = fc[np.isclose(fc["lead_h"], 12.0)]
    by_name = dict(traces)
    assert by_name["rivercal, 12 h ahead"] == at12[at12["kind"] == "updated"]["value"].tolist()
    assert by_name["DSS, 12 h ahead"] == at12[at12["kind"] == "dss"]["value"].tolist()
    mine = scores[scores["series"] == "0029.Q"].groupby(["lead_from_h", "kind"])["rmse"].mean().unstack("kind")
    assert _raw(driver, "#scores tbody tr td:nth-of-type(2)") == pytest.approx(mine["updated"].tolist(), rel=1e-12)
    assert _raw(driver, "#scores tbody tr td:nth-of-type(3)") == pytest.approx(mine["dss"].tolist(), rel=1e-12)
    # the network map: mean level bias per station, cm
    _open(driver, url + "/map")
    levels = scores[scores["series"].str.rpartition(".")[2] != "Q"]
    bias = levels.groupby([levels["series"].str.rpartition(".")[0], "kind"])["bias"].mean().unstack("kind") * 100
    for row in driver.find_elements(By.CSS_SELECTOR, "#map-table tbody tr"):
        station = row.get_attribute("data-station")
        cells = row.find_elements(By.CSS_SELECTOR, "td")
        assert float(cells[0].get_attribute("data-raw")) == pytest.approx(bias.loc[station, "dss"], rel=1e-12)
        assert float(cells[1].get_attribute("data-raw")) == pytest.approx(bias.loc[station, "updated"], rel=1e-12)
    assert _errors(driver) == []


def test_a_cycle_committed_while_the_page_is_open_appears_without_a_reload(served) -> None:
    db, url, driver = served
    _open(driver, url + "/")
    before = int(driver.find_element(By.ID, "latest").get_attribute("data-cycle"))
    driver.execute_script("window.__sameDocument = 'yes'")
    new = add_cycle(db)
    assert new == before + 1
    WebDriverWait(driver, 20).until(
        lambda d: d.find_element(By.ID, "latest").get_attribute("data-cycle") == str(new))
    assert driver.execute_script("return window.__sameDocument") == "yes"  # the page was not reloaded
    assert int(driver.execute_script("return document.body.dataset.updates")) >= 1
    with Store(db, readonly=True) as store:
        est = store.estimates(store.get_run("dash"))
    fa = est[(est["cycle"] == new) & (est["parameter"] == "FA")]["value"].iloc[0]
    assert _raw(driver, 'tr[data-parameter="FA"] td:nth-of-type(1)') == [fa]
    assert driver.find_element(By.ID, "issued").get_attribute("data-kind") == "updated"  # the new cycle's
    assert _errors(driver) == []


def _digest(db: Path) -> str:
    h = hashlib.sha256()
    for suffix in ("", "-wal"):
        path = Path(f"{db}{suffix}")
        h.update(path.read_bytes() if path.exists() else b"")
    return h.hexdigest()


def test_only_reading_is_possible(served) -> None:
    db, url, driver = served
    host, port = urlparse(url).hostname, urlparse(url).port
    before = _digest(db)
    for method in ("POST", "PUT", "DELETE", "PATCH", "OPTIONS"):
        for path in ("/", "/cycles", "/api/version", "/static/dashboard.js"):
            status, headers, _ = request(host, port, method, path, body=b"cycle=99")
            assert status == 405 and headers["allow"] == "GET, HEAD", (method, path)
    for path in ("/static/../../../../etc/passwd", "/static/..%2F..%2F..%2F..%2Fetc%2Fpasswd",
                 "/static/%2e%2e/%2e%2e/pyproject.toml", "/../../etc/passwd", "/static/run.sqlite",
                 f"/static/{db}", "/static//etc/passwd", "/run.sqlite"):
        status, _, body = request(host, port, "GET", path)
        assert status == 404, path
        assert b"root:" not in body and b"SQLite format" not in body
    status, headers, _ = request(host, port, "GET", "/")
    assert status == 200 and "script-src 'self'" in headers["content-security-policy"]
    assert headers["x-content-type-options"] == "nosniff"
    # a form in the page cannot write either: the browser's POST is refused too
    _open(driver, url + "/")
    status = driver.execute_script(
        "return fetch('/', {method: 'POST', body: 'x'}).then(r => r.status)")
    assert status == 405
    time.sleep(0.2)
    assert _digest(db) == before  # the store did not change
    with Store(db, readonly=True) as store:
        assert store.integrity_check() == []
