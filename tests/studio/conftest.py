"""The browser for the studio's tests: headless chromium (software WebGL) driven by selenium,
with generous timeouts (a busy 2-core machine draws slowly).

One chromium serves all the browser tests of a module (started at the first, quit after the
last); each test gets it on an empty page and leaves it on one (a page left open would go on
drawing its scene on the CPU). A browser that no longer answers is replaced."""

from __future__ import annotations

import contextlib
import shutil

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")


def _start(profile):
    """Headless chromium (software WebGL through SwiftShader) driven by selenium."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed")
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (
        "--headless=new",
        "--no-sandbox",
        "--use-angle=swiftshader",
        "--enable-unsafe-swiftshader",
        # no multisampling: on SwiftShader it makes each frame several times slower (a frame
        # of the studio's page: ~0.5 s instead of ~1.5 s, a screenshot ~0.5 s instead of
        # ~10 s); the tests look at colours and shapes, not at smoothed edges
        "--webgl-antialiasing-mode=none",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-dev-shm-usage",
        "--window-size=1024,700",  # fewer pixels for software WebGL to draw
        f"--user-data-dir={profile}",
    ):
        options.add_argument(flag)
    options.page_load_strategy = "normal"
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(300)
    driver.set_script_timeout(300)
    # selenium's own HTTP wait for chromedriver's answer (120 s by default): a starved
    # renderer can take longer than that to answer one command
    driver.command_executor.client_config.timeout = 300
    return driver


@pytest.fixture(scope="module")
def _chromium(tmp_path_factory):
    """The module's chromium: a one-element list, so that a test can replace a dead one."""
    if CHROMIUM is None or CHROMEDRIVER is None:
        pytest.skip(
            "chromium and chromedriver are not installed "
            "(apt-get install -y chromium chromium-driver)"
        )
    holder = [_start(tmp_path_factory.mktemp("chromium-profile"))]
    try:
        yield holder
    finally:
        if holder[0] is not None:
            holder[0].quit()


@pytest.fixture
def browser(_chromium, tmp_path_factory):
    """The module's chromium on an empty page; left on an empty page after the test."""
    if _chromium[0] is None:
        _chromium[0] = _start(tmp_path_factory.mktemp("chromium-profile"))
    driver = _chromium[0]
    yield driver
    try:
        driver.get("about:blank")  # stop drawing the test's page (its server is gone)
    except Exception:  # chromium or chromedriver died or hangs: the next test gets a new one
        _chromium[0] = None
        with contextlib.suppress(Exception):
            driver.quit()
