"""``dsim serve`` in a real browser: headless Chromium (Debian's ``chromium``)
driven by Playwright against a real ``dsim serve`` process.  A user uploads an
FMU, finds it, assembles and saves a scene, runs it and watches the live
progress reach the end, runs it again, compares the two runs against a baseline,
edits a parameter set and sweeps the step.

Screenshots of every view go to a temporary folder, and to ``$DSIM_SCREENSHOTS``
when it is set (``make screenshots`` writes docs/serve/ that way).  Skipped, with
the reason, when Playwright or Chromium is missing.
"""
from __future__ import annotations

import io
import os
import re
import shutil
from pathlib import Path

import pytest

from tests.support.serve_fixtures import ServerProcess

sync_api = pytest.importorskip(
    "playwright.sync_api", reason="the browser tests need Playwright's Python package "
                                  "(make test installs it): they did not run")
CHROMIUM = os.environ.get("DSIM_CHROMIUM") or shutil.which("chromium") or \
    shutil.which("chromium-browser")
if not CHROMIUM:
    pytest.skip("no Chromium found (install Debian's chromium: apt-get install chromium, or "
                "set DSIM_CHROMIUM): the browser tests did not run", allow_module_level=True)

#: Chromium on a machine without a network or a display (and as root)
ARGUMENTS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--no-first-run",
             "--disable-quic"]


@pytest.fixture(scope="module")
def browser():
    with sync_api.sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, args=ARGUMENTS)
        yield launched
        launched.close()


@pytest.fixture
def shots(tmp_path):
    """Takes full-page screenshots named after the view."""
    targets = [tmp_path] + ([Path(os.environ["DSIM_SCREENSHOTS"])]
                            if os.environ.get("DSIM_SCREENSHOTS") else [])

    def shoot(page, name: str, whole: bool = True) -> Path:
        path = tmp_path / f"{name}.png"
        page.screenshot(path=str(path), full_page=whole)
        for folder in targets[1:]:
            folder.mkdir(parents=True, exist_ok=True)
            shutil.copy(path, folder / path.name)
        return path
    return shoot


def _color_pixels(png: bytes, rgb: tuple[int, int, int]) -> int:
    """How many pixels of a PNG are (nearly) the colour ``rgb``."""
    import matplotlib.image as image
    import numpy as np

    pixels = image.imread(io.BytesIO(png), format="png")[:, :, :3] * 255
    return int((np.abs(pixels - np.array(rgb)).max(axis=2) < 40).sum())


def _id(page) -> int:
    return int(re.search(r"/(\d+)(\?|$)", page.url).group(1))


def test_upload_assemble_run_watch_compare_in_a_browser(browser, built, tmp_path, shots):
    server = ServerProcess(tmp_path / "db.sqlite")
    page = browser.new_page(viewport={"width": 1280, "height": 900})
    errors = []
    page.on("pageerror", lambda error: errors.append(str(error)))
    try:
        _scenario(page, server.url, built, shots)
    finally:
        page.close()
        server.stop()
    assert not errors, errors


def _scenario(page, url: str, built, shots) -> None:
    expect = sync_api.expect
    # upload an FMU
    page.goto(url + "/")
    shots(page, "home")
    page.set_input_files("#upload-form input[type=file]", str(built["fmus"] / "SpringMass.fmu"))
    page.click("#upload-form button")
    page.wait_for_url(re.compile(r"/models/\d+$"))
    model = _id(page)
    expect(page.locator("h1")).to_contain_text("SpringMass")
    expect(page.locator("#variables")).to_contain_text("k_ground[1]")
    shots(page, "model", whole=False)  # its 83 variables go on below
    # find it
    page.goto(url + "/models")
    page.fill("#model-search", "spring")
    expect(page.locator("#model-table tbody tr")).to_have_count(1)
    page.fill("#model-search", "no such thing")
    expect(page.locator("#model-table")).to_contain_text("no model matches")
    page.fill("#model-search", "")
    expect(page.locator("#model-table tbody tr a")).to_have_count(1)
    shots(page, "models")

    # assemble the two-mass scene of seed 5.3.1 and save it
    page.goto(url + "/scenes/new")
    page.fill("input[name=name]", "two_masses")
    page.fill("input[name=description]", "two spring-mass FMUs glued by a flexible joint")
    rows = page.locator(".component-row")
    for k, (name, parameters, record) in enumerate([
            ("left", "n = 1\nm[1] = 10\nk_ground[1] = 100", "x[1]"),
            ("right", "n = 2\nm[1] = 10\nm[2] = 10\nk[1] = 100\nF0[2] = 10", "x[1] x[2]")]):
        row = rows.nth(k)
        row.locator("input[name=component_name]").fill(name)
        row.locator("select[name=component_model]").select_option(str(model))
        row.locator("textarea").fill(parameters)
        row.locator("input[name=component_record]").fill(record)
    page.click("#add-component")  # htmx adds an empty row, which is left out
    expect(page.locator(".component-row")).to_have_count(3)
    joint = page.locator(".joint-row").first
    for field, value in (("joint_name", "j1"), ("joint_a", "left.P"), ("joint_b", "right.Q"),
                         ("joint_k0", "100"), ("joint_c0", "14.14")):
        joint.locator(f"input[name={field}]").fill(value)
    page.fill("input[name=stop]", "40")
    shots(page, "assemble")
    page.click("#save-scene")
    page.wait_for_url(re.compile(r"/scenes/\d+$"))
    scene = _id(page)
    expect(page.locator("#diagram svg g.component")).to_have_count(2)
    expect(page.locator("#diagram svg path.joint")).to_have_count(1)
    shots(page, "scene")

    # run it and watch the live progress reach the end
    page.click("#run-button")
    page.wait_for_url(re.compile(r"/runs/\d+$"))
    first = _id(page)
    page.wait_for_function("() => { const p = document.getElementById('progress');"
                           " return p.value > 0.05 && p.value < 0.95; }", timeout=60_000)
    expect(page.locator("#status-text")).to_have_text("running")
    shots(page, "run-live")
    page.wait_for_selector("#live[data-finished='1']", timeout=120_000)
    expect(page.locator("#status-text")).to_have_text("completed")
    expect(page.locator("#progress-text")).to_contain_text("100%")
    assert int(page.locator("#live").get_attribute("data-samples")) >= 5
    # look at the chart: uPlot drew the joint force, the fourth signal, in purple
    drawn = page.locator("#chart-signals canvas").screenshot()
    assert _color_pixels(drawn, (0x94, 0x67, 0xbd)) > 100
    shots(page, "run")

    # a second run with a coarser step
    page.goto(f"{url}/scenes/{scene}")
    page.fill("#run-form input[name=step]", "0.02")
    page.click("#run-button")
    page.wait_for_url(re.compile(r"/runs/\d+$"))
    second = _id(page)
    page.wait_for_selector("#live[data-finished='1']", timeout=120_000)
    expect(page.locator("#status-text")).to_have_text("completed")

    # compare them: the first is the baseline
    page.goto(f"{url}/scenes/{scene}/compare?run={first}&run={second}&column=right.x[2]")
    page.click(f"#baseline-{first}")
    expect(page.locator(f"#verdict-{second}")).to_contain_text("differs")
    expect(page.locator(f"#verdict-{second} tr.fail").first).to_contain_text("outside")
    page.wait_for_selector("#chart-overlay[data-curves='2']")
    shots(page, "compare")

    # a parameter set: a heavier load, as a new scene
    page.goto(f"{url}/scenes/{scene}/parameters")
    page.fill("input[data-name='right.F0[2]']", "20")
    page.fill("input[name=set_name]", "heavy")
    shots(page, "parameters", whole=False)
    page.click("#save-parameters")
    page.wait_for_url(re.compile(r"parameter_set=resources/parameters_1.ssv"))
    expect(page.locator("#parameter-sets")).to_contain_text("heavy")

    # a run with a model parameter set in the scene page's form (dsim run --set)
    page.goto(f"{url}/scenes/{scene}")
    page.click("#run-parameters summary:has-text('component right')")
    field = page.locator("#run-parameters input[name='parameter:right.F0[2]']")
    expect(field).to_have_attribute("placeholder", "10")
    field.fill("20")
    page.fill("#run-form input[name=stop]", "2")
    shots(page, "run-parameters", whole=False)
    page.click("#run-button")
    page.wait_for_url(re.compile(r"/runs/\d+$"))
    page.wait_for_selector("#live[data-finished='1']", timeout=120_000)
    expect(page.locator("#status-text")).to_have_text("completed")
    expect(page.locator("#inputs")).to_contain_text("--set 'right.F0[2]=20.0'")

    # a sweep of the step, and the cheapest configuration for an error
    page.goto(f"{url}/scenes/{scene}")
    page.fill("#sweep-form input[name=step]", "0.04 0.02 0.01")
    page.fill("#sweep-form input[name=stop]", "2")
    page.click("#sweep-form button")
    page.wait_for_url(re.compile(r"/runs/\d+$"))
    page.wait_for_selector("#sweep-table", timeout=120_000)  # the page reloads at the end
    expect(page.locator("#sweep-table tbody tr")).to_have_count(3)
    page.fill("#target-form input[name=target]", "0.01")
    page.click("#target-form button")
    expect(page.locator("#cheapest")).to_contain_text("Cheapest for error ≤ 0.01")
    shots(page, "sweep")

    # a design of experiments over two model parameters: KPIs, sensitivity, plots
    page.goto(f"{url}/scenes/{scene}")
    page.fill("#sweep-form textarea[name=vary]", "right.k[1]=100:400:log\nright.m[2]=5:20")
    page.select_option("#sweep-form select[name=design]", "lhs")
    page.fill("#sweep-form input[name=samples]", "8")
    page.fill("#sweep-form textarea[name=kpis]", "max(right.x[2])\nargmax(right.x[2])")
    page.fill("#sweep-form input[name=stop]", "2")
    page.click("#sweep-form button")
    page.wait_for_url(re.compile(r"/runs/\d+$"))
    page.wait_for_selector("#sensitivity-table", timeout=120_000)  # written at the end
    expect(page.locator("#sweep-table tbody tr")).to_have_count(8)
    expect(page.locator(".ranking").first).to_contain_text("right.m[2]")
    page.wait_for_function("document.getElementById('kpi-plot').naturalWidth > 0")
    shots(page, "doe_sweep")
