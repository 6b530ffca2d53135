"""The session protocol: the little every engine adapter implements so one driver can run it.

An adapter's ``open(scene, integrator, dt)`` builds its engine's model of the Scene, places the
scene's t = 0 state the engine's own exact way, and returns a :class:`Session`. The driver
(``engines/driver.py``) owns everything else: the sampling plan, recording, blow-up detection and
timing, the same for every engine.

Reading is split in two on purpose: ``read_raw`` copies the engine's own state into one flat
row (the cheapest read the engine allows, called once per sample), and ``convert`` turns the
rows of a whole run into crosscheck's convention at once (vectorised, and with the history some
conversions need: a 2D angle read as an arctan2 is made continuous with the angular velocity).
``read`` is the two together for one sample.

A session may offer a fused fast path, ``record(n_samples, k, rows)``, that steps and reads a
whole run without a Python call per sample (MuJoCo's and Pymunk's compiled loops). It must fill
exactly the rows the generic path (``advance(k)`` then ``read_raw()``) fills and stop at the same
sample; tests/engines/test_driver.py checks every fast path against the generic one bit for bit.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from crosscheck.errors import StepFailure  # noqa: F401 - sessions raise it; re-exported


@runtime_checkable
class Session(Protocol):
    """One engine model of one Scene, one integrator, one step size."""

    row_width: int  # floats per raw row

    def advance(self, n: int) -> None:
        """Take n steps. Raises StepFailure when the engine reports a failed step."""

    def read_raw(self) -> np.ndarray | list[float]:
        """The current state as one flat row of ``row_width`` floats, in the engine's terms."""

    def convert(self, rows: np.ndarray, t: np.ndarray
                ) -> tuple[tuple[np.ndarray, ...], dict[str, np.ndarray]]:
        """(T, row_width) rows at times t -> ((com, rot, vel, omega), extras) in crosscheck's
        convention (state.py); extras are engine-specific (T, ...) series."""

    def set_state(self, com, rot, vel, omega) -> None:
        """Place a normalised state (one sample of ``convert``'s arrays)."""

    def check(self) -> list[str]:
        """Problems with the engine's settings found before stepping (empty: none)."""

    def effective(self, arrays: tuple[np.ndarray, ...]) -> dict[str, Any]:
        """Settings read back from the engine after the run (``arrays``: the converted run)."""

    def close(self) -> None:
        """Release the engine's resources."""


def read(session: Session, t: float = 0.0) -> tuple[np.ndarray, ...]:
    """The current state of a session in crosscheck's convention: (com, rot, vel, omega)."""
    row = np.asarray(session.read_raw(), float)[None]
    arrays, _ = session.convert(row, np.array([float(t)]))
    return tuple(a[0] for a in arrays)
