"""FCL's signed distance (compare/convex_gap.py) against crosscheck's closed forms, at the
accuracy docs/metrics.md states: overlapping pairs to 1e-6 m, a capsule's separation exactly,
other separations to 2e-6 m within 1 mm of contact, 1e-4 m within 1 cm."""

import numpy as np
import pytest

from crosscheck.compare import contact_metrics as cm
from crosscheck.compare import convex_gap
from crosscheck.rotations import quat_to_matrix
from crosscheck.scene.shapes import Box, Capsule, Cylinder, Sphere

pytestmark = pytest.mark.skipif(not convex_gap.available(), reason="python-fcl is a dependency")


def _poses(seed: int, m: int = 1500, far: float = 0.0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(m, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rot_b = quat_to_matrix(q)
    q = rng.normal(size=(m, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    rot_a = quat_to_matrix(q)
    origin_a = rng.normal(size=(m, 3)) * 0.2 + far
    origin_b = origin_a + rng.normal(size=(m, 3)) * 0.25
    return rot_a, origin_a, rot_b, origin_b


@pytest.mark.parametrize("other", [Box(np.array([0.3, 0.2, 0.4])), Capsule(0.1, 0.3),
                                   Cylinder(0.2, 0.3)], ids=lambda s: s.kind)
def test_sphere_pairs_match_the_exact_signed_distance(other):
    sphere = Sphere(0.15)
    rot_a, origin_a, rot_b, origin_b = _poses(2, far=1e3)  # far from the origin as well
    exact = cm.pair_gap(sphere, rot_a, origin_a, other, rot_b, origin_b)  # sdf_B(c) - r
    got = convex_gap.gap(sphere, rot_a, origin_a, other, rot_b, origin_b)
    err = np.abs(got - exact)
    assert (exact < 0).sum() > 300 and ((exact > 0) & (exact < 1e-2)).sum() > 30
    assert err[exact < 0].max() < 2e-6
    exact_refine = other.kind == "capsule"
    touching = (exact > 0) & (exact < 1e-3)
    near = (exact > 0) & (exact < 1e-2)
    assert err[touching].max() < (1e-12 if exact_refine else 2e-6)
    assert err[near].max() < (1e-12 if exact_refine else 1e-4)


def test_box_pairs_match_the_separating_axis_depth():
    a, b = Box(np.array([0.4, 0.3, 0.2])), Box(np.array([0.2, 0.5, 0.3]))
    rot_a, origin_a, rot_b, origin_b = _poses(1)
    exact = cm.pair_gap(a, rot_a, origin_a, b, rot_b, origin_b)
    got = convex_gap.gap(a, rot_a, origin_a, b, rot_b, origin_b)
    overlap = exact < 0
    assert overlap.sum() > 300
    assert np.abs(got - exact)[overlap].max() < 1e-9


def test_a_capsule_separation_is_refined_exactly_in_either_order():
    cap, sphere = Capsule(0.1, 0.3), Sphere(0.15)
    rot_a, origin_a, rot_b, origin_b = _poses(5)
    exact = cm.pair_gap(sphere, rot_a, origin_a, cap, rot_b, origin_b)
    got = convex_gap.gap(cap, rot_b, origin_b, sphere, rot_a, origin_a)
    apart = exact > 0
    assert np.abs(got - exact)[apart].max() < 1e-12


def test_a_mesh_is_measured_as_its_convex_hull():
    # A unit cube given as a mesh with an extra vertex inside: the hull is the cube, so the gap
    # to a box equals the box-box separating-axis gap.
    from crosscheck.scene.shapes import Mesh

    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    verts = np.vstack([corners, [[0.1, 0.0, 0.0]]])
    mesh = Mesh(path=None, vertices=verts, faces=np.zeros((0, 3), int))
    cube, other = Box(np.ones(3)), Box(np.array([0.3, 0.6, 0.2]))
    rot_a, origin_a, rot_b, origin_b = _poses(9, m=300)
    origin_b = origin_a + (origin_b - origin_a) * 3.0  # a unit cube needs wider spacing
    exact = cm.pair_gap(cube, rot_a, origin_a, other, rot_b, origin_b)
    got = convex_gap.gap(mesh, rot_a, origin_a, other, rot_b, origin_b)
    overlap = exact < 0
    assert overlap.sum() > 50
    assert np.abs(got - exact)[overlap].max() < 1e-9
