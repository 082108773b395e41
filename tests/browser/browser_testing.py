"""A headless Chromium for the page's tests and for ``scripts/page_screenshot.py``.

Debian's ``chromium`` and ``chromium-driver`` (``apt-get install chromium
chromium-driver``, done by ``scripts/test.sh``), driven by selenium through
``/usr/bin/chromedriver`` given explicitly, so nothing is downloaded at run time. WebGL
runs on SwiftShader (the CPU), so no GPU is needed.
"""

from __future__ import annotations

import importlib.util
import shutil
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

CHROMEDRIVER = "/usr/bin/chromedriver"
#: Flags of a quiet, offline, throw-away browser with WebGL on the CPU.
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                  "--no-first-run", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync",
                  "--disable-dev-shm-usage", "--use-angle=swiftshader",
                  "--enable-unsafe-swiftshader", "--window-size=1400,900")


def chromium_binary() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


def missing_browser() -> str | None:
    """Why no browser test can run here, or None."""
    if importlib.util.find_spec("selenium") is None:
        return "selenium is not installed (deploy/requirements-check.txt)"
    if chromium_binary() is None or not Path(CHROMEDRIVER).exists():
        return (f"no chromium or no {CHROMEDRIVER}: apt-get install chromium "
                "chromium-driver (scripts/test.sh does it as root)")
    return None


def start_chromium(profile: Path) -> Any:
    """A new headless Chromium with a fresh profile in ``profile``.

    Its downloads go to ``driver.download_dir`` (``profile / "downloads"``); its console
    is read by ``driver.get_log("browser")``.
    """
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = chromium_binary()
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={profile / 'profile'}")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    downloads = profile / "downloads"
    downloads.mkdir(parents=True, exist_ok=True)
    options.add_experimental_option("prefs", {"download.default_directory": str(downloads),
                                              "download.prompt_for_download": False})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.execute_cdp_cmd("Browser.setDownloadBehavior",
                           {"behavior": "allow", "downloadPath": str(downloads)})
    driver.download_dir = downloads
    return driver


def wait_for(check: Callable[[], Any], timeout: float = 30.0, what: str = "the page") -> Any:
    """Poll ``check()`` until it returns something true; fail after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def body_state(driver: Any, name: str) -> str | None:
    """``document.body.dataset[name]`` (the page's ready, generate and repair states)."""
    return driver.execute_script(f"return document.body.dataset.{name} || null")


def downloaded(driver: Any, suffix: str, timeout: float = 20.0) -> Path:
    """The first finished download whose name ends with ``suffix``: not a
    ``.crdownload``, not empty, and of the same size at two polls in a row (the browser
    may show the file under its final name before its bytes are all written)."""
    sizes: dict[Path, int] = {}

    def find() -> Path | None:
        for path in driver.download_dir.iterdir():
            if path.name.endswith(suffix) and not path.name.endswith(".crdownload"):
                size = path.stat().st_size
                if size > 0 and sizes.get(path) == size:
                    return path
                sizes[path] = size
        return None

    return wait_for(find, timeout, f"a downloaded *{suffix}")


def console_errors(driver: Any) -> list[str]:
    """The browser console's errors since the last call."""
    return [entry["message"] for entry in driver.get_log("browser")
            if entry.get("level") == "SEVERE"]


def pixel_spread(png: bytes) -> float:
    """Standard deviation of a PNG's grey levels (0 for a blank picture)."""
    import io

    import numpy as np
    from PIL import Image

    return float(np.asarray(Image.open(io.BytesIO(png)).convert("L"), np.float64).std())
