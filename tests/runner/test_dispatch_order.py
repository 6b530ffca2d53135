"""The order the runner dispatches cells in (crosscheck.runner.schedule): shared references
first, then the heaviest cells (plan.expected_work), the rest in the matrix's order. A long
cell dispatched last runs alone while the other worker idles; longest first keeps the run's
wall time near its work divided by the workers (on a fresh clone's gate the Wachs disc, 52 s,
came last of 307 cells: 120 s of wall)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from crosscheck.runner import schedule
from crosscheck.runner.plan import build_matrix, expected_work
from crosscheck.scene.loader import load_case

CASES = Path(__file__).resolve().parents[2] / "cases"


class OneAtATime:
    """A backend with one worker that finishes each task as soon as it is polled, recording
    the order of submission."""

    def __init__(self):
        self.submitted, self._running = [], None

    def free(self) -> bool:
        return self._running is None

    def submit(self, task):
        self.submitted.append(task["id"])
        self._running = task

    def poll(self, timeout):
        done, self._running = self._running, None
        if done is None:
            return []
        status = {"status": "ok", "path": "ref.npz"} if done["kind"] == "reference" else {}
        return [(done, status)]


def test_references_then_the_heaviest_cells_then_the_matrix_order():
    tasks = [
        {"kind": "cell", "id": "rigid-a", "work": 0.0},
        {"kind": "cell", "id": "fluid-small", "work": 5.0},
        {"kind": "cell", "id": "needs-ref", "work": 0.0, "depends_on": "ref"},
        {"kind": "cell", "id": "rigid-b"},
        {"kind": "cell", "id": "fluid-large", "work": 10.0},
        {"kind": "reference", "id": "ref"},
    ]
    backend = OneAtATime()
    schedule(tasks, backend, on_result=lambda task, result: None, poll_interval=0.0)
    # the reference's dependent goes to the front once the reference is done (it finishes a
    # case while other references run); then the fluid cells by work, then the rigid ones
    assert backend.submitted == ["ref", "needs-ref", "fluid-large", "fluid-small", "rigid-a",
                                 "rigid-b"]


def test_a_fluid_cells_work_is_its_cells_times_its_steps_a_rigid_cells_its_bodies():
    """The Wachs disc (48 x 540 cells, 20 s at 0.01333) weighs more than the dam break and the
    cavity of the gate; a rigid cell weighs its bodies times its steps, so the ten-box stack
    (the gate's longest rigid cell, 20 s with the LCP solver) goes before a single body and
    after the fluid cells. Halving the step doubles the work."""
    wachs = load_case(CASES / "fluid" / "sedimentation_wachs.toml")
    assert expected_work(wachs, 0.01333) == pytest.approx(48 * 540 * 20.0 / 0.01333, rel=1e-12)
    assert expected_work(wachs, 0.01333 / 2) == pytest.approx(2 * expected_work(wachs, 0.01333),
                                                              rel=1e-12)
    for other in ("dam_break.toml", "lid_driven_cavity.toml", "floating_box.toml"):
        scene = load_case(CASES / "fluid" / other)
        assert expected_work(scene, scene.run.dt) < expected_work(wachs, wachs.run.dt)
    stack = load_case(next(CASES.rglob("stack_10.toml")))
    single = load_case(next(CASES.rglob("damped_oscillator.toml")))
    assert len(stack.bodies) == 10 and len(single.bodies) == 1
    assert expected_work(stack, 0.001) == pytest.approx(10 * stack.run.duration / 0.001, rel=1e-12)
    assert expected_work(single, 0.001) < expected_work(stack, 0.001) \
        < expected_work(load_case(CASES / "fluid" / "tank_at_rest.toml"), 0.01)


def test_the_matrix_carries_each_cells_work():
    wachs = load_case(CASES / "fluid" / "sedimentation_wachs.toml")
    scenes = [dataclasses.replace(wachs, name="w2"), wachs]
    matrix = build_matrix(scenes, cost=False)
    assert [t["work"] for t in matrix.tasks] == [expected_work(wachs, wachs.run.dt)] * 2
