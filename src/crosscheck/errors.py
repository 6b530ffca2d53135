"""Error types that carry enough context for a user to fix their input without a traceback."""

from __future__ import annotations

from pathlib import Path


class CrosscheckError(Exception):
    """Base of every error crosscheck raises on purpose (exit status 2 in the CLI)."""


class CaseError(CrosscheckError):
    """A case file that cannot be understood.

    The message always names the file, the field path (``bodies[2].shape.box.size``) and what was
    expected, so a user can fix the file without reading Python.
    """

    def __init__(self, file: str | Path | None, field: str, expected: str, got: object = None):
        self.file = str(file) if file is not None else "<case>"
        self.field = field
        self.expected = expected
        self.got = got
        where = f"{self.file}: {field}" if field else self.file
        msg = f"{where}: expected {expected}"
        if got is not None:
            msg += f", got {_describe(got)}"
        super().__init__(msg)


class EngineUnavailable(CrosscheckError):
    """An engine cannot run a scene; the reason becomes a 'not applicable' result."""


def _describe(value: object) -> str:
    text = repr(value)
    if len(text) > 80:
        text = text[:77] + "..."
    return f"{text} ({type(value).__name__})"


class StepFailure(Exception):
    """An engine reported that a step failed or diverged (a typed divergence, as dm_control's
    PhysicsError): the run driver records it as the run's failure at the time of the sample
    being stepped to, never as a crash. Here, below the simulators and the adapters, so both
    can raise it."""
