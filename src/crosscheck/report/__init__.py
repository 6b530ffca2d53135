"""Reports of a run, written atomically into the output folder.

``results.json`` (versioned schema, :mod:`.results`), ``summary.md`` (:mod:`.markdown`),
``junit.xml`` (:mod:`.junit`) and ``index.html`` (:mod:`.html`, self-contained with plots).
docs/reports.md describes each file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


def write_all(doc: dict[str, Any], outdir: str | Path,
              series_cells: list[dict[str, Any]] | None = None) -> dict[str, str]:
    """Write every report; a failing writer is recorded in the returned map, never raised,
    so one broken report (say, a plot) cannot lose the others."""
    from crosscheck.report import html, junit, markdown, results

    written: dict[str, str] = {}
    for name, fn in (("results.json", lambda: results.write(doc, outdir)),
                     ("summary.md", lambda: markdown.write(doc, outdir)),
                     ("junit.xml", lambda: junit.write(doc, outdir)),
                     ("index.html", lambda: html.write(doc, outdir, series_cells))):
        try:
            written[name] = str(fn())
        except Exception as exc:  # pragma: no cover - reported to the caller
            written[name] = f"failed: {type(exc).__name__}: {exc}"
    return written


def write_light(doc: dict[str, Any], outdir: str | Path) -> None:
    """The cheap reports (results.json, summary.md), rewritten as cells arrive."""
    from crosscheck.report import markdown, results

    results.write(doc, outdir)
    markdown.write(doc, outdir)
