"""``--json`` for commands that print results: human text to stderr, one JSON document to stdout.

A CI step can then pipe ``crosscheck run ... --json`` into ``jq`` while the progress lines and
tables still reach the log.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from contextlib import contextmanager, redirect_stdout
from typing import Any


def add_json_flag(parser) -> None:
    parser.add_argument("--json", action="store_true",
                        help="print one JSON document on stdout (human output goes to stderr)")


@contextmanager
def human_output(as_json: bool) -> Iterator[None]:
    """Send what the command prints for people to stderr when the caller asked for JSON."""
    if as_json:
        with redirect_stdout(sys.stderr):
            yield
    else:
        yield


def emit(payload: Any) -> None:
    print(json.dumps(payload, indent=1, default=_default))


def _default(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    return str(value)
