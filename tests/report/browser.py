"""Headless Chromium for the report tests: Debian's ``chromium`` driven by Playwright.

``make test`` installs the package where missing (the Makefile's ``browser`` target). A test
that needs it and does not find it fails under ``CI=true`` (a CI machine that lost its browser
must not turn the check green by skipping it) and is skipped with the remedy elsewhere.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import pytest

CANDIDATES = ("chromium", "chromium-browser")


def chromium() -> str:
    """The Chromium executable, or fail (CI) / skip (elsewhere) saying how to get it."""
    path = next((p for p in map(shutil.which, CANDIDATES) if p), None)
    missing = []
    if path is None:
        missing.append("Debian's chromium (make browser, or apt-get install chromium)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        missing.append("playwright (pip install -e '.[dev]')")
    if missing:
        message = "the browser check needs " + " and ".join(missing)
        if os.environ.get("CI") == "true":
            pytest.fail(message + ": CI must run it", pytrace=False)
        pytest.skip(message)
    return path


@dataclass
class PageCheck:
    errors: list[str] = field(default_factory=list)  # console errors, page errors, failed loads
    images: list[dict] = field(default_factory=list)  # src (shortened), complete, naturalWidth
    matrix: dict[str, list[str]] = field(default_factory=dict)  # case -> runs with a cell
    title: str = ""


def open_page(browser, path: Path, screenshot: Path | None = None) -> PageCheck:
    """Load ``path`` in a fresh page; collect console errors, the images and the matrix cells;
    write a screenshot of the top of the page."""
    check = PageCheck()
    page = browser.new_page(viewport={"width": 1400, "height": 1000})
    page.on("console", lambda m: check.errors.append(f"console {m.type}: {m.text}")
            if m.type == "error" else None)
    page.on("pageerror", lambda e: check.errors.append(f"page error: {e}"))
    page.on("requestfailed", lambda r: check.errors.append(f"failed to load {r.url[:80]}"))
    page.goto(path.resolve().as_uri(), wait_until="load")
    check.title = page.title()
    check.images = page.evaluate(
        "Array.from(document.images).map(i => ({src: i.src.slice(0, 40), complete: i.complete,"
        " naturalWidth: i.naturalWidth}))")
    check.matrix = page.evaluate(
        "Object.fromEntries(Array.from(document.querySelectorAll('#overview tr[data-case]'))"
        ".map(r => [r.dataset.case, Array.from(r.querySelectorAll('td[data-run]'))"
        ".map(td => td.dataset.run)]))")
    if screenshot is not None:
        page.screenshot(path=str(screenshot))
    page.close()
    return check
