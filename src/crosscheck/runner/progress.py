"""Progress display: a rich progress bar on a terminal, one plain line per cell otherwise (CI)."""

from __future__ import annotations

import sys
from typing import Any

STATUS_LABEL = {"pass": "PASS", "fail": "FAIL", "blowup": "BLOWUP", "error": "ERROR",
                "timeout": "TIMEOUT", "not_applicable": "N/A", "ok": "REF", "regression": "REGR"}


def describe(result: dict[str, Any]) -> str:
    status = result.get("status", "?")
    label = STATUS_LABEL.get(status, status.upper())
    if result.get("kind") == "reference":
        text = f"{label:<7} reference {result['case']} {result.get('engine')}-" \
               f"{result.get('integrator')}"
        if status != "ok":
            text = f"{'REF-' + label:<7} reference {result['case']}: {_first(result)}"
        return text
    head = f"{label:<7} {result['case']} {result['engine']}-{result['integrator']} " \
           f"dt={result['dt']:g}"
    seconds = result.get("cell_seconds")
    if seconds is not None:
        head += f" ({seconds:.1f} s)"
    worst = result.get("worst")
    if status in ("pass", "fail") and worst:
        head += f"  worst {worst['metric']} = {worst['value']:.3g} (limit {worst['limit']:g})"
    elif status not in ("pass",):
        head += f"  {_first(result)}"
    return head


def _first(result: dict[str, Any]) -> str:
    return (result.get("reason") or "").splitlines()[0][:160] if result.get("reason") else ""


class PlainProgress:
    def __init__(self, total: int, stream=None):
        self.total = total
        self.count = 0
        self.stream = stream or sys.stdout

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def advance(self, result: dict[str, Any]) -> None:
        self.count += 1
        width = len(str(self.total))
        print(f"[{self.count:>{width}}/{self.total}] {describe(result)}", file=self.stream,
              flush=True)

    def message(self, text: str) -> None:
        print(text, file=self.stream, flush=True)


class RichProgress:
    def __init__(self, total: int):
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
        )

        self.console = Console()
        self.progress = Progress(TextColumn("[bold]crosscheck"), BarColumn(),
                                 MofNCompleteColumn(), TimeElapsedColumn(),
                                 TextColumn("{task.description}"), console=self.console,
                                 transient=False)
        self.task = self.progress.add_task("", total=total)

    def __enter__(self):
        self.progress.__enter__()
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def advance(self, result: dict[str, Any]) -> None:
        status = result.get("status")
        if status not in ("pass", "ok"):
            color = "yellow" if status == "not_applicable" else "red"
            from rich.text import Text

            self.progress.console.print(Text(describe(result), style=color))
        self.progress.update(self.task, advance=1,
                             description=f"{result.get('case')} {result.get('engine')}")

    def message(self, text: str) -> None:
        self.progress.console.print(text, highlight=False, markup=False)


def make_progress(total: int, mode: str = "auto"):
    """``mode``: "auto" (a bar on a terminal), "bar", "plain"."""
    if mode == "bar" or (mode == "auto" and sys.stdout.isatty()):
        try:
            return RichProgress(total)
        except ImportError:  # pragma: no cover - rich is a dependency
            pass
    return PlainProgress(total)
