"""Take the screenshots of the web page (docs/results/page.png, page-repair.png).

Starts the real server with the shipped model on a free port, opens the page in a
headless Chromium (Debian's ``chromium`` + ``/usr/bin/chromedriver``, as
tests/browser), uploads ``examples/points.ply``, generates (seed 0) and saves the window;
then repairs a ball of that mesh (the sphere brush, right of the view's centre) and saves
the before/after view.

    .venv-test/bin/python scripts/page_screenshot.py [OUT.png] [--mode distance]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from spacemesh_service.server import BackgroundServer  # noqa: E402
from spacemesh_service.settings import Settings  # noqa: E402
from tests.browser.browser_testing import (  # noqa: E402
    body_state,
    missing_browser,
    start_chromium,
    wait_for,
)


def repair(driver: object, url: str, points: Path, folder: Path, out: str) -> None:
    """Repair a ball of the seed-0 mesh of ``points`` on the page; save the window."""
    import httpx
    from selenium.webdriver.common.action_chains import ActionChains

    mesh = httpx.post(url + "/generate", params={"seed": 0, "format": "obj"}, timeout=120,
                      files={"file": (points.name, points.read_bytes())})
    mesh.raise_for_status()
    path = folder / "mesh.obj"
    path.write_bytes(mesh.content)
    driver.find_element("id", "tab-repair").click()
    driver.find_element("id", "repair-file").send_keys(str(path))
    wait_for(lambda: "no region" in driver.find_element("id", "selection").text,
             what="the mesh")
    driver.find_element("css selector", "input[name=tool][value=sphere]").click()
    before = driver.find_element("id", "before")  # a torus: aim off its hole
    ActionChains(driver).move_to_element_with_offset(
        before, before.size["width"] // 5, 0).click().perform()
    wait_for(driver.find_element("id", "repair-run").is_enabled, what="a region")
    driver.find_element("id", "repair-seed").send_keys("0")
    driver.find_element("id", "repair-run").click()
    wait_for(lambda: body_state(driver, "repair") in ("done", "failed"), 120, "the repair")
    driver.save_screenshot(out)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default=str(ROOT / "docs/results/page.png"))
    parser.add_argument("--points", default=str(ROOT / "examples/points.ply"))
    parser.add_argument("--mode", default="distance",
                        choices=["shaded", "wireframe", "degree", "distance"])
    parser.add_argument("--repair-out", default=str(ROOT / "docs/results/page-repair.png"))
    args = parser.parse_args()
    reason = missing_browser()
    if reason:
        print(f"page_screenshot: {reason}", file=sys.stderr)
        return 2
    server = BackgroundServer(Settings(host="127.0.0.1", port=0, grpc=False,
                                       log_level="warning")).start()
    try:
        with tempfile.TemporaryDirectory() as profile:
            driver = start_chromium(Path(profile))
            try:
                driver.get(server.url + "/")
                wait_for(lambda: body_state(driver, "ready") == "true", what="the page")
                driver.find_element("id", "file").send_keys(args.points)
                driver.find_element("id", "generate-seed").send_keys("0")
                wait_for(driver.find_element("id", "run").is_enabled, what="the points")
                driver.find_element("id", "run").click()
                wait_for(lambda: body_state(driver, "generate") in ("done", "failed"), 120,
                         "the mesh")
                if body_state(driver, "generate") != "done":
                    print(driver.find_element("id", "error").text, file=sys.stderr)
                    return 1
                driver.execute_script("const s = document.getElementById('mode');"
                                      f"s.value = '{args.mode}';"
                                      "s.dispatchEvent(new Event('change'));")
                Path(args.out).parent.mkdir(parents=True, exist_ok=True)
                driver.save_screenshot(args.out)
                repair(driver, server.url, Path(args.points), Path(profile), args.repair_out)
            finally:
                driver.quit()
    finally:
        server.stop()
    print(f"wrote {args.out} and {args.repair_out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
