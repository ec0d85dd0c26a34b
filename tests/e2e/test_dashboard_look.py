"""The dashboard as a forecaster sees it: every page at 1280×800 in headless chromium, screenshots kept, and checks
that look — no overlapping labels, legends that match the data they describe, units on every axis and column.

One store, one server and one browser for the module. The screenshots (the first screen and the whole page)
are written under the test's temporary folder and their paths printed (``pytest -s`` shows them).
"""

from __future__ import annotations

import base64
import re
from pathlib import Path

import pytest
from selenium.webdriver.common.by import By
from selenium.webdriver.support.ui import WebDriverWait

from rivercal.store import Store
from tests.dashboard_store import HIGH, build_store
from tests.e2e.browser import chrome, start_dashboard

N_CYCLES = 14
PAGES = ("/", "/forecast", "/estimates", "/forecasts", "/map", "/cycles")
WIDTH, HEIGHT = 1280, 800

#: Bounding boxes of every visible text of the page's plotly figures, per figure (tick labels, axis titles,
#: legend entries, annotations, map labels): [figure id, [[text, left, top, right, bottom], ...]].
_FIGURE_TEXTS = """
return Array.from(document.querySelectorAll('.plot')).map(function (plot) {
  var boxes = [];
  plot.querySelectorAll('svg text').forEach(function (t) {
    var r = t.getBoundingClientRect();
    var style = window.getComputedStyle(t);
    if (t.textContent.trim() && r.width > 0 && r.height > 0 && style.visibility !== 'hidden'
        && style.display !== 'none' && Number(style.opacity || 1) > 0) {
      boxes.push([t.textContent.trim(), r.left, r.top, r.right, r.bottom]);
    }
  });
  return [plot.id, boxes];
});
"""


@pytest.fixture(scope="module")
def served(tmp_path_factory):
    folder = tmp_path_factory.mktemp("dashboard-look")
    db = build_store(folder / "run.sqlite", N_CYCLES)
    driver = chrome(folder / "profile")
    try:
        proc, url = start_dashboard(db, poll=30)
    except BaseException:
        driver.quit()
        raise
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False})
    shots = folder / "screenshots"
    shots.mkdir()
    try:
        yield db, url, driver, shots
    finally:
        driver.quit()
        proc.terminate()
        proc.wait(timeout=30)


def _open(driver, url: str) -> None:
    driver.get(url)
    WebDriverWait(driver, 30).until(lambda d: d.execute_script("return document.body.dataset.ready === '1'"))


def _shoot(driver, shots: Path, page: str) -> list[Path]:
    """The first screen (1280×800) and the whole page as PNG files."""
    name = page.strip("/") or "now"
    first, whole = shots / f"{name}.png", shots / f"{name}-full.png"
    assert driver.save_screenshot(str(first))
    data = driver.execute_cdp_cmd("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True})
    whole.write_bytes(base64.b64decode(data["data"]))
    return [first, whole]


def _overlaps(a: list, b: list, slack: float = 1.0) -> bool:
    return a[1] + slack < b[3] and b[1] + slack < a[3] and a[2] + slack < b[4] and b[2] + slack < a[4]


def _rgb(css: str) -> tuple[int, int, int]:
    numbers = [int(float(v)) for v in re.findall(r"[\d.]+", css)[:3]]
    assert len(numbers) == 3, css
    return numbers[0], numbers[1], numbers[2]


def test_every_page_at_1280x800_is_kept_as_a_screenshot_and_fits_the_width(served) -> None:
    _, url, driver, shots = served
    written = []
    for page in PAGES:
        _open(driver, url + page + "?run=dash")
        assert driver.execute_script("return window.innerWidth") == WIDTH
        written += _shoot(driver, shots, page)
        # nothing wider than the screen: no sideways scrolling to read a table or a figure
        assert driver.execute_script("return document.documentElement.scrollWidth") <= WIDTH, page
        errors = [e["message"] for e in driver.get_log("browser") if e["level"] in ("SEVERE", "ERROR")]
        assert errors == [], page
    for path in written:
        assert path.stat().st_size > 10_000 and path.read_bytes()[:4] == b"\x89PNG"
    print("screenshots:", *written, sep="\n  ")


def test_no_label_of_a_figure_overlaps_another(served) -> None:
    _, url, driver, _ = served
    checked = 0
    for page in PAGES:
        _open(driver, url + page + "?run=dash")
        for plot, boxes in driver.execute_script(_FIGURE_TEXTS):
            for i, a in enumerate(boxes):
                for b in boxes[i + 1:]:
                    assert not _overlaps(a, b), f"{page} #{plot}: {a[0]!r} overlaps {b[0]!r} ({a[1:]} / {b[1:]})"
            checked += len(boxes)
        # and no figure overlaps another figure or a heading
        blocks = driver.execute_script(
            "return Array.from(document.querySelectorAll('.plot, h2, h3, table')).map(function (e) {"
            "var r = e.getBoundingClientRect(); return [e.tagName + '#' + e.id, r.left, r.top, r.right, r.bottom]; })")
        for i, a in enumerate(blocks):
            for b in blocks[i + 1:]:
                assert not _overlaps(a, b), f"{page}: {a[0]} overlaps {b[0]}"
    assert checked > 200  # the map labels, ticks, legends and axis titles of every figure were looked at


def test_the_map_colours_each_station_by_the_sign_of_its_error_as_the_legend_says(served) -> None:
    db, url, driver, _ = served
    _open(driver, url + "/map?run=dash")
    legend = driver.find_element(By.ID, "map-legend").text
    assert "red where the forecasts were too high" in legend and "blue where too low" in legend
    high = _rgb(driver.find_element(By.CSS_SELECTOR, "#map-legend .swatch.high").value_of_css_property(
        "background-color"))
    low = _rgb(driver.find_element(By.CSS_SELECTOR, "#map-legend .swatch.low").value_of_css_property(
        "background-color"))
    assert high[0] > high[2] and low[2] > low[0]
    with Store(db, readonly=True) as store:
        scores = store.scores(store.get_run("dash"))
    levels = scores[scores["series"].str.rpartition(".")[2] != "Q"]
    bias = levels.groupby([levels["series"].str.rpartition(".")[0], "kind"])["bias"].mean().unstack("kind")
    seen = 0
    for kind in ("dss", "updated"):
        plot = driver.find_element(By.ID, f"map-{kind}")
        stations = driver.execute_script("return arguments[0].data[1].text", plot)
        fills = driver.execute_script(
            "return Array.from(arguments[0].querySelectorAll('.scatterlayer .trace')[1].querySelectorAll("
            "'path.point')).map(function (p) { return window.getComputedStyle(p).fill; })", plot)
        assert len(fills) == len(stations) == 5
        for station, fill in zip(stations, fills, strict=True):
            r, _, b = _rgb(fill)
            error = bias.loc[station, kind]
            if kind == "updated":  # the store's rivercal forecasts: too high at HIGH, too low elsewhere
                assert (error > 0) == (station in HIGH)
            assert (r > b) == (error > 0), f"{kind} {station}: error {error * 100:+.2f} cm drawn {fill}"
            seen += 1
    assert seen == 10
    # the table beside the maps: signed cm, the sign of the colour
    for row in driver.find_elements(By.CSS_SELECTOR, "#map-table tbody tr"):
        cell = row.find_elements(By.CSS_SELECTOR, "td")[1]
        assert cell.text.startswith("+" if row.get_attribute("data-station") in HIGH else "-")


def test_every_legend_entry_has_the_colour_of_what_it_names(served) -> None:
    _, url, driver, _ = served
    named = 0
    for page in ("/forecast", "/estimates", "/forecasts"):
        _open(driver, url + page + "?run=dash")
        for plot in driver.find_elements(By.CSS_SELECTOR, ".plot"):
            entries = driver.execute_script(
                "return Array.from(arguments[0].querySelectorAll('.legend .traces')).map(function (g) {"
                "var line = g.querySelector('.legendlines path, .legendpoints path');"
                "var s = line ? window.getComputedStyle(line) : null;"
                "return [g.querySelector('text').textContent, s ? (s.stroke !== 'none' ? s.stroke : s.fill) : '']; })",
                plot)
            for text, colour in entries:
                if text.startswith("DSS"):
                    r, _, b = _rgb(colour)
                    assert r > b, f"{page}: legend {text!r} drawn {colour}"
                    named += 1
                elif text.startswith("rivercal"):
                    r, _, b = _rgb(colour)
                    assert b > r, f"{page}: legend {text!r} drawn {colour}"
                    named += 1
    assert named >= 10


def test_every_axis_and_column_says_its_unit_and_no_number_is_shown_raw(served) -> None:
    _, url, driver, _ = served
    for page in PAGES:
        _open(driver, url + page + "?run=dash")
        for plot in driver.find_elements(By.CSS_SELECTOR, ".plot:not(.map)"):
            title = driver.execute_script("return arguments[0].layout.yaxis.title.text", plot)
            assert re.search(r"\[(m AD|m³/s|m|m\^\(1/3\)/s|-)\]$", title), f"{page}: y axis {title!r}"
        text = driver.find_element(By.TAG_NAME, "main").text
        # a number as a person reads it: no exponent, no negative zero
        assert not re.search(r"\d[eE][-+]\d", text.replace("e+0", "")), f"{page}: a number in exponent form"
        assert not re.search(r"-0\.0+\b(?!\d)", text), f"{page}: a negative zero"
    _open(driver, url + "/forecasts?run=dash&series=0028.h_up&lead=12")
    headers = [h.text for h in driver.find_elements(By.CSS_SELECTOR, "#scores thead th")]
    assert [h for h in headers if "RMSE" in h or "bias" in h] == [
        "RMSE rivercal (cm)", "RMSE DSS (cm)", "bias rivercal (cm)", "bias DSS (cm)"]
    _open(driver, url + "/forecasts?run=dash&series=0029.Q&lead=12")
    assert driver.find_element(By.ID, "scores").get_attribute("data-unit") == "m³/s"
    _open(driver, url + "/map?run=dash")
    assert [h.text for h in driver.find_elements(By.CSS_SELECTOR, "#map-table thead th")][1:] == [
        "DSS (cm)", "rivercal (cm)"]
    _open(driver, url + "/?run=dash")
    units = {r.get_attribute("data-parameter"): r.find_elements(By.CSS_SELECTOR, "td")[4].text
             for r in driver.find_elements(By.CSS_SELECTOR, "#estimates tbody tr")}
    assert units == {"FA": "m^(1/3)/s", "Wd": "m"}


def test_the_map_labels_stay_apart_on_a_narrow_screen(served) -> None:
    """At 700 px the stations 0028 and 0040 (and 0030 and 0031) lie closer than their labels are wide: the page
    moves the labels apart (without that, both pairs overlap on both maps)."""
    _, url, driver, shots = served
    driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                           {"width": 700, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False})
    try:
        _open(driver, url + "/map?run=dash")
        driver.save_screenshot(str(shots / "map-700.png"))
        labels = 0
        for plot, boxes in driver.execute_script(_FIGURE_TEXTS):
            for i, a in enumerate(boxes):
                for b in boxes[i + 1:]:
                    assert not _overlaps(a, b), f"#{plot}: {a[0]!r} overlaps {b[0]!r}"
            labels += sum(1 for box in boxes if re.fullmatch(r"\d{4}", box[0]))
        assert labels == 10
        # at 360 px the five stations have no room for all their labels: those that find no free place are left
        # out (their markers keep the name on hover), and no label overlaps another or leaves its figure
        driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                               {"width": 360, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False})
        _open(driver, url + "/map?run=dash")
        for plot, boxes in driver.execute_script(_FIGURE_TEXTS):
            names = [b for b in boxes if re.fullmatch(r"\d{4}", b[0])]
            frame = driver.execute_script("var r = document.getElementById(arguments[0]).getBoundingClientRect();"
                                          "return [r.left, r.top, r.right, r.bottom];", plot)
            left_out = driver.execute_script("return document.getElementById(arguments[0]).dataset.labelsLeftOut",
                                             plot)
            assert len(names) + int(left_out or 0) == 5, (plot, names, left_out)
            for i, a in enumerate(names):
                assert frame[0] <= a[1] and a[3] <= frame[2], f"#{plot}: {a[0]!r} leaves the figure"
                for b in names[i + 1:]:
                    assert not _overlaps(a, b), f"#{plot}: {a[0]!r} overlaps {b[0]!r}"
    finally:
        driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                               {"width": WIDTH, "height": HEIGHT, "deviceScaleFactor": 1, "mobile": False})
