"""The report as a reader sees it: each page opened in a real browser (Debian's chromium,
headless, driven by selenium through chromium-driver) at 1400 px wide. No horizontal page
scroll, no table cut behind a scrollbar of its own, every image loaded, no Markdown left in
the text, every link landing somewhere.

`scripts/setup.sh --test` (make test, CI) installs the browser; where it cannot be had the
tests skip, saying why, except under CI, where they fail."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from harness import repo
from harness.report import pipeline

from fixture_results import results_with
from tests.records import doubled

WIDTH = 1400
HEIGHT = 1000
BROWSERS = ("chromium", "chromium-browser", "google-chrome")
DRIVER = "chromedriver"


def _unavailable(reason: str) -> None:
    if os.environ.get("CI"):
        pytest.fail(f"the browser tests must run in CI: {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    try:
        from selenium import webdriver
        from selenium.common.exceptions import WebDriverException
        from selenium.webdriver.chrome.service import Service
    except ImportError as exc:
        _unavailable(f"selenium is not installed ({exc}): run make setup-test")
    binary = next((found for name in BROWSERS if (found := shutil.which(name))), None)
    driver_path = shutil.which(DRIVER)
    if binary is None or driver_path is None:
        _unavailable("chromium or chromedriver is not installed: run `scripts/setup.sh --test` "
                     "as root, or apt-get install chromium chromium-driver")
    options = webdriver.ChromeOptions()
    options.binary_location = binary
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu",
                     "--disable-dev-shm-usage", "--hide-scrollbars",
                     f"--window-size={WIDTH},{HEIGHT}"):
        options.add_argument(argument)
    try:
        driver = webdriver.Chrome(options=options, service=Service(driver_path))
    except WebDriverException as exc:
        _unavailable(f"chromium did not start: {exc.msg}")
    try:
        yield driver
    finally:
        driver.quit()


@pytest.fixture(scope="module")
def two_machines(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The fixture report with the threads experiment measured on two machines, the others on
    a machine they do not record: a page each under machines/, one of them on top."""
    tmp = tmp_path_factory.mktemp("browser")
    root = results_with(tmp, "strategies", "threads", "grid", "trajectory", "accuracy")
    doubled(root / "threads", lambda row, first: {
        "machine_id": ("a" if first else "b") * 16, "machine": "Box x2",
        "measured_at": f"2026-0{1 if first else 2}-01T00:00:00+00:00"})
    out = tmp / "report"
    pipeline.render(root, out)
    return out


# What the page tells about itself, read in the browser.
PAGE_FACTS = """
const root = document.documentElement;
return JSON.stringify({
  scrollWidth: root.scrollWidth, clientWidth: root.clientWidth,
  cut: [...document.querySelectorAll('.table-wrap')].filter(w => w.scrollWidth > w.clientWidth)
       .map(w => w.querySelector('tr').textContent.slice(0, 80)),
  images: [...document.images].map(i => ({src: i.getAttribute('src'),
                                          ok: i.complete && i.naturalWidth > 0})),
  text: document.body.textContent,
  links: [...document.querySelectorAll('a[href]')].map(a => a.getAttribute('href')),
  ids: [...document.querySelectorAll('[id]')].map(e => e.id),
});
"""


def page_facts(browser: object, page: Path) -> dict:
    browser.get(page.as_uri())  # type: ignore[attr-defined]
    # Wait for every image, loaded or failed, before reading them.
    browser.execute_async_script(  # type: ignore[attr-defined]
        "const done = arguments[0];"
        "Promise.all([...document.images].map(i => i.decode().catch(() => null)))"
        ".then(() => done());")
    return json.loads(browser.execute_script(PAGE_FACTS))  # type: ignore[attr-defined]


def check_page(browser: object, page: Path) -> None:
    facts = page_facts(browser, page)
    assert facts["clientWidth"] <= WIDTH
    assert facts["scrollWidth"] <= facts["clientWidth"], "the page scrolls sideways"
    assert not facts["cut"], f"tables cut behind a scrollbar: {facts['cut']}"
    assert facts["images"], "no figure on the page"
    broken = [i["src"] for i in facts["images"] if not i["ok"]]
    assert not broken, f"images not loaded: {broken}"
    for mark in ("**", "`"):
        at = facts["text"].find(mark)
        assert at < 0, f"literal {mark!r} in the text: ...{facts['text'][max(0, at - 80):at + 80]}"
    ids = set(facts["ids"])
    for href in facts["links"]:
        parts = urlsplit(href)
        assert not parts.scheme and not parts.netloc, f"a link leaves the report: {href}"
        if not parts.path:
            assert parts.fragment in ids, f"link {href} lands on no element"
        else:
            assert (page.parent / unquote(parts.path)).is_file(), f"link {href}: no such file"


def test_every_page_of_a_two_machine_report(browser: object, two_machines: Path) -> None:
    pages = sorted(two_machines.rglob("report.html"))
    assert [p.relative_to(two_machines).as_posix() for p in pages] == [
        f"machines/{'a' * 16}/report.html", f"machines/{'b' * 16}/report.html",
        "machines/unknown/report.html", "report.html"]
    for page in pages:
        check_page(browser, page)


def test_a_folded_warning_opens_where_the_summary_links(browser: object,
                                                       two_machines: Path) -> None:
    from selenium.webdriver.common.by import By

    browser.get((two_machines / "report.html").as_uri())  # type: ignore[attr-defined]
    link = browser.find_element(  # type: ignore[attr-defined]
        By.CSS_SELECTOR, '.summary a[href$="-warnings"]')
    target = browser.find_element(  # type: ignore[attr-defined]
        By.ID, link.get_attribute("href").rsplit("#", 1)[1])
    assert target.tag_name == "details" and not target.get_attribute("open")
    target.find_element(By.TAG_NAME, "summary").click()
    assert target.get_attribute("open") is not None
    assert target.find_element(By.TAG_NAME, "table").is_displayed()


def test_the_committed_report(browser: object) -> None:
    """published/report/report.html as committed, rendered from published/results/ (and each
    machine's page)."""
    report = repo.PUBLISHED_REPORT_DIR
    pages = sorted(report.rglob("report.html"))
    if not pages:
        pytest.skip("no rendered report in published/report/")
    for page in pages:
        check_page(browser, page)
