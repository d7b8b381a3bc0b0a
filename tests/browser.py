"""Headless Chromium for the browser tests (the explorer, the report's first screen, a docs
page): Debian's chromium and chromedriver, which .ci/run installs; a test is skipped with a
message saying so when they are absent."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

CHROMIUM = next((p for p in ("/usr/bin/chromium", "/usr/bin/chromium-browser")
                 if os.access(p, os.X_OK)), None)
CHROMEDRIVER = "/usr/bin/chromedriver" if os.access("/usr/bin/chromedriver", os.X_OK) else None


@contextmanager
def headless_chromium(width: int, height: int, *, prefs: dict[str, Any] | None = None,
                      exact_viewport: bool = False) -> Iterator[Any]:
    """A selenium driver of a headless Chromium window ``width`` x ``height``; with
    ``exact_viewport`` the page's viewport itself is that size (the window's toolbar
    excluded).  The driver and its chromedriver process are ended on exit."""
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip("no Chromium/chromedriver on this machine (.ci/run installs Debian's "
                    "chromium and chromium-driver with apt-get)")
    pytest.importorskip("selenium", reason="the browser tests need selenium (test extra)")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                f"--window-size={width},{height + (200 if exact_viewport else 0)}"):
        opts.add_argument(arg)
    if prefs:
        opts.add_experimental_option("prefs", prefs)
    service = Service(CHROMEDRIVER)
    driver = webdriver.Chrome(service=service, options=opts)
    try:
        if exact_viewport:
            driver.execute_cdp_cmd("Emulation.setDeviceMetricsOverride", {
                "width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
        else:
            driver.set_window_size(width, height)
        yield driver
    finally:
        driver.quit()
        proc = getattr(service, "process", None)
        if proc is not None and proc.poll() is None:
            proc.kill()
