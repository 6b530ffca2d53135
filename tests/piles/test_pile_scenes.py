"""The pile scenes of benchmarks/bench_piles.py (tests/piles/pile_scenes.py) are sound, and the
in-house engine keeps the smallest pile in its bin without sinking."""

from __future__ import annotations

import numpy as np
import pytest
from pile_scenes import (
    DT,
    HALF_DIAGONAL,
    MASS,
    SIDE,
    R,
    boxes,
    pile_2d,
    spheres,
    with_mujoco_solver,
)
from scipy.spatial import cKDTree

from crosscheck.compare.contact_metrics import penetration
from crosscheck.engines.driver import run
from crosscheck.engines.inhouse import InhouseEngine


def _reach(shape) -> float:
    """A body's farthest point from its centre: no two bodies whose centres are farther apart
    than the sum can touch, whatever their orientations."""
    return R if shape.kind in ("sphere", "circle") else (
        HALF_DIAGONAL if shape.kind == "box" and len(shape.size) == 3 else SIDE / np.sqrt(2))


def _check(pile, n: int) -> None:
    sc = pile.scene
    assert len(sc.bodies) == pile.n == n
    assert all(b.mass == MASS for b in sc.bodies)
    assert all(b.material.friction == 0.5 and b.material.restitution == 0.0 for b in sc.bodies)
    pos = np.array([b.position for b in sc.bodies])
    reach = np.array([_reach(b.shape) for b in sc.bodies])
    # Nothing overlaps at t = 0, with a margin: pairs closer than their reaches plus 1 mm.
    pairs = cKDTree(pos).query_pairs(2 * reach.max() + 1e-3, output_type="ndarray")
    d = np.linalg.norm(pos[pairs[:, 0]] - pos[pairs[:, 1]], axis=1)
    assert np.all(d > reach[pairs[:, 0]] + reach[pairs[:, 1]] + 1e-3), "bodies overlap at t = 0"
    # Above the ground, clear of it.
    assert np.all(pos[:, -1] - reach > 1e-3)
    if pile.inner:
        lo, hi = np.array(pile.inner[0::2]), np.array(pile.inner[1::2])
        horiz = pos[:, :-1]
        assert np.all(horiz - reach[:, None] > lo + 1e-3) and np.all(horiz + reach[:, None]
                                                                     < hi - 1e-3)
        # The walls enclose the inside and stand higher than the highest start.
        for w in sc.statics:
            assert w.position[-1] + w.shape.size[-1] / 2 > pos[:, -1].max() + reach.max()
    # The staggered grid: about ten layers (3D) or twenty rows (2D), never one flat sheet.
    assert len(np.unique(np.round(pos[:, -1], 6))) >= 8


@pytest.mark.parametrize("n", [200, 1000])
def test_sphere_bins(n):
    _check(spheres(n), n)


def test_other_scenes():
    _check(spheres(200, walls=False), 200)
    _check(boxes(200), 200)
    _check(boxes(200, walls=False), 200)
    _check(pile_2d(200), 200)
    cg = with_mujoco_solver(spheres(200), "cg")
    assert cg.scene.engine_options["mujoco"] == {"solver": "cg"}


@pytest.mark.slow
def test_sphere_bin_5000():
    _check(spheres(5000), 5000)


def test_inhouse_keeps_the_pile_in_the_bin():
    """200 spheres dropped into the bin for 0.6 s with soft_step: no sphere leaves the bin or
    sinks through the ground, and no pair is deeper than 1 mm, the committed sphere-pile case's
    bound for the non-MuJoCo engines (cases/contact/sphere_pile.toml; benchmarks/results/piles.md
    measured 0.05 mm at 0.3 s, so the bound leaves room for the heavier pile at 0.6 s)."""
    pile = spheres(200, duration=0.6)
    traj = run(InhouseEngine(), pile.scene, "symplectic_euler+soft_step", DT,
               cost=None).trajectory
    assert traj.failure is None
    com = traj.com[-1]
    lo, hi = np.array(pile.inner[0::2]), np.array(pile.inner[1::2])
    assert np.all(com[:, :2] > lo + R - 1e-3) and np.all(com[:, :2] < hi - R + 1e-3)
    assert np.all(com[:, 2] > R - 1e-3)
    # Fallen: every sphere is below where the top layer started (1.05 m).
    assert com[:, 2].max() < 1.0
    gap = penetration(pile.scene, traj).rows.gap
    assert -gap.min() < 1e-3


def test_mujoco_solver_option_reaches_the_model():
    """[engine_options.mujoco] solver = "cg" (the benchmark's fastest MuJoCo setting) is what
    the compiled model steps with; the default stays Newton."""
    from crosscheck.engines.mujoco import MujocoEngine

    pile = spheres(20, duration=0.01)
    for scene, want in ((pile.scene, "mjSOL_NEWTON"),
                        (with_mujoco_solver(pile, "cg").scene, "mjSOL_CG")):
        traj = run(MujocoEngine(), scene, "euler", DT, cost=None).trajectory
        assert traj.meta["effective"]["contact"]["solver"] == want


def test_mujoco_opens_a_5000_sphere_pile_and_its_arena_grows_linearly():
    """MuJoCo's automatic arena grows faster than N^1.5 and cannot be allocated at 5000 bodies
    ("Could not allocate memory" from the compiler, measured on 4.0.0); the adapter sizes it
    from the body count instead, so the benchmark's largest pile opens and steps."""
    import mujoco

    from crosscheck.engines.mujoco import MujocoEngine, arena_bytes

    pile = spheres(5000, duration=0.002)
    model = MujocoEngine().build(pile.scene, "euler", 1e-3)
    assert model.model.narena == arena_bytes(5000)
    assert arena_bytes(5000) - arena_bytes(1000) == 5 * (arena_bytes(1000) - arena_bytes(200))
    mujoco.mj_step(model.model, model.data)
    assert model.data.warning.number.sum() == 0
