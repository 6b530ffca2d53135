"""``sweep.html``: the page of ``crosscheck sweep``, for a person choosing an integrator.

The sweep's figure (error against cost with the Pareto front, error against dt with the floor
and the stability frontier) embedded, then the sweep's table and notes (the text of
``sweep.md``, rendered), and a link to the run's index.html with every cell. One file, no
scripts. The Markdown here is the sweep's own (headings, pipe tables, bullet lists, inline
code), so a small converter suffices.
"""

from __future__ import annotations

import base64
import html
import re
from pathlib import Path

CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222;max-width:1500px}
table{border-collapse:collapse;font-size:12px;margin:0.5em 0}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td:first-child,th:first-child,td:last-child{text-align:left}
img{max-width:100%;display:block;margin:0.5em 0}
"""


def _inline(text: str) -> str:
    return re.sub(r"`([^`]*)`", r"<code>\1</code>", html.escape(text, quote=False))


def _cells(line: str) -> list[str]:
    return [c.strip().replace("\\|", "|") for c in
            re.split(r"(?<!\\)\|", line.strip().strip("|"))]


def markdown_to_html(text: str) -> str:
    """Headings, pipe tables, bullet lists and paragraphs, with inline code."""
    out: list[str] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
        elif line.startswith("#"):
            level = min(len(line) - len(line.lstrip("#")), 6)
            out.append(f"<h{level}>{_inline(line[level:].strip())}</h{level}>")
            i += 1
        elif line.startswith("|"):
            rows = []
            while i < len(lines) and lines[i].startswith("|"):
                if not re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", lines[i].strip()):
                    rows.append(_cells(lines[i]))
                i += 1
            head, body = rows[0], rows[1:]
            out.append("<table><tr>" + "".join(f"<th>{_inline(c)}</th>" for c in head)
                       + "</tr>" + "".join("<tr>" + "".join(f"<td>{_inline(c)}</td>"
                                                              for c in r) + "</tr>"
                                           for r in body) + "</table>")
        elif line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{_inline(lines[i][2:])}</li>")
                i += 1
            out.append("<ul>" + "".join(items) + "</ul>")
        else:
            para = []
            while i < len(lines) and lines[i].strip() and not lines[i].startswith(("#", "|",
                                                                                   "- ")):
                para.append(lines[i])
                i += 1
            out.append(f"<p>{_inline(' '.join(para))}</p>")
    return "\n".join(out)


def render(case: str, markdown: str, figure_png: bytes) -> str:
    image = base64.b64encode(figure_png).decode("ascii")
    return (f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>sweep of "
            f"{html.escape(case)}</title><style>{CSS}</style></head><body>"
            f"<img alt='{html.escape(case)}: sweep' src='data:image/png;base64,{image}'>"
            f"{markdown_to_html(markdown)}<p><a href='index.html'>every cell of the sweep "
            "(index.html)</a></p></body></html>")


def write(outdir: str | Path, case: str, markdown: str, figure_png: bytes) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "sweep.html", render(case, markdown, figure_png))
