"""Shared fluid runs: each validation case is run once per session and reused by its tests."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from crosscheck.scene.loader import load_case
from crosscheck.sim.fluid import run_fluid

CASES = Path(__file__).resolve().parents[2] / "cases" / "fluid"

_runs: dict = {}


def case(name: str):
    return load_case(CASES / f"{name}.toml")


def shortened(scene, duration: float):
    return dataclasses.replace(scene, run=dataclasses.replace(scene.run, duration=duration))


def run_case(name: str, integrator: str, duration: float | None = None):
    key = (name, integrator, duration)
    if key not in _runs:
        scene = case(name)
        if duration is not None:
            scene = shortened(scene, duration)
        _runs[key] = (scene, run_fluid(scene, integrator))
    return _runs[key]


@pytest.fixture(scope="session")
def runs():
    return run_case


@pytest.fixture(scope="session")
def fluid_case():
    """``fluid_case(name, duration=None)``: a case of cases/fluid, optionally shortened."""

    def load(name: str, duration: float | None = None):
        scene = case(name)
        return scene if duration is None else shortened(scene, duration)

    return load
