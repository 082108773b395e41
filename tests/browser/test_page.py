"""The web page at ``/`` in a real headless Chromium against the real server (tiny
exported model): it loads without console errors, a file uploaded through the page gives
a rendered mesh whose downloads equal the REST responses byte for byte, a bad file shows
its error, and a repair round trip works."""

from __future__ import annotations

import json

import httpx
import pytest
from service_testing import as_ply, mesh_file

from spacemesh.examples import icosphere
from spacemesh.io import load_mesh
from spacemesh.topology import check_topology
from tests.browser.browser_testing import (
    body_state,
    console_errors,
    downloaded,
    pixel_spread,
    wait_for,
)

pytestmark = pytest.mark.slow

#: Grey-level spread above which a viewer shows something (a blank one has ~0).
DRAWN = 3.0


@pytest.fixture(scope="module")
def page(browser, server):
    """The page, loaded and ready, with the console read."""
    browser.get(server.url + "/")
    wait_for(lambda: body_state(browser, "ready"), what="the page to start")
    assert body_state(browser, "ready") == "true", browser.find_element("id", "error").text
    return browser


def element(driver, id_: str):
    return driver.find_element("id", id_)


def test_the_page_loads_without_console_errors(page, server):
    assert console_errors(page) == []
    labels = {e.get_attribute("name") for e in element(page, "options").find_elements(
        "css selector", "input, select")}
    # every generate option of the service's table but format (downloads pick it)
    assert labels == {"seed", "steps", "sampler", "start", "start_time", "target_vertices",
                      "tolerance", "samples", "raw", "surface", "face_type"}
    assert httpx.get(server.url + "/static/vendor/three/LICENSE").status_code == 200


def test_generate_renders_and_downloads_the_rest_bytes(page, server, case, tmp_path):
    cloud = tmp_path / "cloud.ply"
    cloud.write_bytes(as_ply(case.points))
    blank = pixel_spread(element(page, "viewer").screenshot_as_png)
    element(page, "file").send_keys(str(cloud))
    element(page, "generate-seed").send_keys(str(case.good_seed))
    wait_for(lambda: element(page, "run").is_enabled(), what="the file to load")
    element(page, "run").click()
    wait_for(lambda: body_state(page, "generate") in ("done", "failed"), 60, "the mesh")
    assert body_state(page, "generate") == "done", element(page, "error").text
    assert element(page, "progress").get_attribute("value") == "1"
    stats = element(page, "stats").text
    assert f"seed {case.good_seed}" in stats and "fit-coverage" in stats
    element(page, "show-points").click()  # the mesh alone
    drawn = pixel_spread(element(page, "viewer").screenshot_as_png)
    assert blank < 1.0 and drawn > DRAWN, (blank, drawn)
    for mode in ("wireframe", "degree", "distance"):
        page.execute_script("const s = document.getElementById('mode');"
                            f"s.value = '{mode}'; s.dispatchEvent(new Event('change'));")
        assert pixel_spread(element(page, "viewer").screenshot_as_png) > DRAWN, mode

    for fmt in ("ply", "json"):  # ply: asked again with the seed; json: the stream's own
        page.find_element("css selector", f"#downloads button[data-format={fmt}]").click()
        got = downloaded(page, f".{fmt}").read_bytes()
        rest = httpx.post(server.url + "/generate", params={"seed": case.good_seed,
                          "format": fmt}, files={"file": ("cloud.ply", cloud.read_bytes())})
        assert rest.status_code == 200 and got == rest.content, fmt
    assert console_errors(page) == []


def test_a_bad_file_shows_the_error(page, tmp_path):
    bad = tmp_path / "broken.ply"
    bad.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n1 2\n")
    element(page, "file").send_keys(str(bad))
    error = element(page, "error")
    wait_for(error.is_displayed, what="the error message")
    assert "(400)" in error.text or "(422)" in error.text, error.text
    assert "ply" in error.text.lower()
    element(page, "run").click()  # the server's answer to the request itself
    wait_for(lambda: body_state(page, "generate") == "failed", 30, "the failed request")
    assert element(page, "error").is_displayed() and element(page, "error").text
    console_errors(page)  # the failed fetches are logged by the browser; nothing else


def test_a_repair_round_trip(page, tmp_path):
    sphere = icosphere(1)
    path = tmp_path / "sphere.obj"
    path.write_bytes(mesh_file(sphere, "obj"))
    element(page, "tab-repair").click()
    element(page, "repair-file").send_keys(str(path))
    before = element(page, "before")
    wait_for(lambda: pixel_spread(before.screenshot_as_png) > DRAWN, what="the mesh")
    from selenium.webdriver.common.action_chains import ActionChains

    ActionChains(page).move_to_element(before).click().perform()  # pick the face in front
    wait_for(lambda: element(page, "repair-run").is_enabled(), what="a picked face")
    region = json.loads(element(page, "selection").text.removeprefix("region: "))
    assert len(region["faces"]) == 1  # a picked face (its hole would be refilled alike)
    page.find_element("css selector", "input[name=tool][value=sphere]").click()
    ActionChains(page).move_to_element(before).click().perform()  # a ball around the hit
    region = json.loads(element(page, "selection").text.removeprefix("region: "))
    assert set(region) == {"sphere"} and region["sphere"]["radius"] > 0
    element(page, "repair-steps").send_keys("4")
    element(page, "repair-run").click()
    wait_for(lambda: body_state(page, "repair") in ("done", "failed"), 60, "the repair")
    assert body_state(page, "repair") == "done", element(page, "repair-error").text
    assert pixel_spread(element(page, "after").screenshot_as_png) > DRAWN
    stage = element(page, "repair-stage").text
    assert stage.startswith("done:") and int(stage.split()[1]) > 0, stage  # highlighted
    page.find_element("css selector", "#repair-downloads button[data-format=obj]").click()
    repaired = load_mesh(downloaded(page, ".obj"))
    assert check_topology(repaired).is_closed_oriented_manifold
    assert console_errors(page) == []


def test_fill_holes_where_the_server_finds_regions(page, server, tmp_path):
    from tests.repair.test_repair_cut import open_icosphere

    auto = httpx.get(server.url + "/static/config.json").json()["auto_regions"]
    buttons = page.find_elements("css selector", "#auto button")
    assert [b.get_attribute("data-auto") for b in buttons] == auto
    if "holes" not in auto:
        pytest.skip("this server finds no repair regions by itself")
    mesh, _ = open_icosphere()
    path = tmp_path / "open.off"
    path.write_bytes(mesh_file(mesh, "off"))
    element(page, "tab-repair").click()
    element(page, "repair-file").send_keys(str(path))
    wait_for(lambda: "no region" in element(page, "selection").text, what="the open mesh")
    page.find_element("css selector", "#auto button[data-auto=holes]").click()
    assert json.loads(element(page, "selection").text.removeprefix("region: ")) == {
        "auto": "holes"}
    element(page, "repair-run").click()
    wait_for(lambda: body_state(page, "repair") in ("done", "failed"), 60, "the repair")
    assert body_state(page, "repair") == "done", element(page, "repair-error").text
    assert "closed true" in element(page, "repair-stats").text
    assert console_errors(page) == []


def test_the_api_key_field(browser, start_server, generator, case, tmp_path):
    key = "browser-test-key-0123456789"
    keys = tmp_path / "keys.txt"
    keys.write_text(key + "\n")
    server = start_server(generator, api_keys=keys)
    browser.get(server.url + "/")  # the page and its assets need no key
    wait_for(lambda: body_state(browser, "ready") == "true", what="the page to start")
    assert console_errors(browser) == []
    first, second = tmp_path / "one.ply", tmp_path / "two.ply"
    for path in (first, second):
        path.write_bytes(as_ply(case.points))
    element(browser, "file").send_keys(str(first))
    error = element(browser, "error")
    wait_for(error.is_displayed, what="the error message")
    assert "(401)" in error.text, error.text
    console_errors(browser)  # the refused fetch
    element(browser, "api-key").send_keys(key)
    element(browser, "file").send_keys(str(second))
    wait_for(lambda: not element(browser, "error").is_displayed(), what="the key to work")
    element(browser, "run").click()
    wait_for(lambda: body_state(browser, "generate") in ("done", "failed"), 60, "the mesh")
    assert body_state(browser, "generate") == "done", element(browser, "error").text
    # kept in the page's memory only: nothing in storage or cookies
    assert browser.execute_script("return localStorage.length + sessionStorage.length") == 0
    assert browser.get_cookies() == []
