"""Mass properties: closed forms, polyhedral meshes, bounding box and point sampling.

Tessellated reference shapes are checked with *bounds*, not a guessed tolerance: every
trimesh.creation primitive used here is convex with its vertices on the true surface, so the mesh
lies inside the true shape, and it contains the same shape with a smaller radius ``r_in``
(the smallest distance from the axis or centre to a face plane, measured on the mesh). Mass and
every diagonal entry of the inertia about the centre are integrals of non-negative functions,
hence monotone under inclusion: ``f(r_in) <= f(mesh) <= f(r)``. The tests also assert that this
bracket is narrow (relative width < 2e-3), so it actually constrains the formula.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.integrate import quad
from scipy.spatial.transform import Rotation

from crosscheck.scene import massprops as mp

MESHES = Path(__file__).resolve().parents[1] / "cases" / "meshes"
L_BRACKET = MESHES / "l_bracket.obj"
NOT_CLOSED = MESHES / "not_closed.obj"

# L profile in the xz-plane, extruded along y in [0, 0.1]: a 0.3 x 0.04 foot and a 0.04 x 0.16
# upright above its left end (same shape as cases/meshes/l_bracket.obj before its rotation).
L_PROFILE = [(0.0, 0.0), (0.3, 0.0), (0.3, 0.04), (0.04, 0.04), (0.04, 0.2), (0.0, 0.2)]


def l_mesh() -> trimesh.Trimesh:
    n = len(L_PROFILE)
    verts = [(x, 0.0, z) for x, z in L_PROFILE] + [(x, 0.1, z) for x, z in L_PROFILE]
    cap = [(3, 4, 5), (3, 5, 0), (3, 0, 1), (3, 1, 2)]  # fan from the reflex vertex
    faces = list(cap) + [(a + n, c + n, b + n) for a, b, c in cap]
    for i in range(n):
        j = (i + 1) % n
        faces += [(i, j + n, j), (i, i + n, j + n)]
    return trimesh.Trimesh(np.array(verts, float), np.array(faces), process=False)


def transformed(mesh: trimesh.Trimesh, R, t) -> trimesh.Trimesh:
    m = mesh.copy()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    m.apply_transform(T)
    return m


def props_of(mesh, density):
    return mp.mesh_mass_properties(mesh.vertices, mesh.faces, density)


def assert_props_close(a, b, rtol):
    scale = np.abs(b.inertia).max()
    assert a.mass == pytest.approx(b.mass, rel=rtol)
    assert np.abs(a.com - b.com).max() <= rtol * (1.0 + np.abs(b.com).max())
    assert np.abs(a.inertia - b.inertia).max() <= rtol * scale


def assert_bracketed(lower, value, upper, slack=1e-12):
    assert lower * (1 - slack) <= value <= upper * (1 + slack), (lower, value, upper)


# ---------------------------------------------------------------------------------------------
# closed forms
# ---------------------------------------------------------------------------------------------


def test_sphere_closed_form():
    r, rho = 0.3, 800.0
    p = mp.sphere(r, rho)
    m = 4.0 / 3.0 * math.pi * r**3 * rho
    assert p.mass == pytest.approx(m, rel=1e-15)
    np.testing.assert_allclose(p.inertia, np.eye(3) * 2 / 5 * m * r * r, rtol=1e-15)
    np.testing.assert_array_equal(p.com, 0.0)


def test_sphere_against_icosphere_bounds():
    r, rho = 0.3, 800.0
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=r)
    r_in = np.min(np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles[:, 0]))
    assert 1 - (r_in / r) ** 5 < 2e-3
    p = props_of(mesh, rho)
    lo, hi = mp.sphere(r_in, rho), mp.sphere(r, rho)
    assert_bracketed(lo.mass, p.mass, hi.mass)
    I0 = p.about_point(np.zeros(3))
    for k in range(3):
        assert_bracketed(lo.inertia[k, k], I0[k, k], hi.inertia[k, k])


def test_box_closed_form_and_mesh():
    a, b, c, rho = 0.1, 0.4, 0.9, 500.0
    p = mp.box((a, b, c), rho)
    m = a * b * c * rho
    assert p.mass == pytest.approx(m, rel=1e-15)
    np.testing.assert_allclose(
        np.diag(p.inertia), [m * (b * b + c * c) / 12, m * (a * a + c * c) / 12,
                             m * (a * a + b * b) / 12], rtol=1e-15)
    assert np.count_nonzero(p.inertia - np.diag(np.diag(p.inertia))) == 0
    # a box mesh is represented exactly by the polyhedral formula
    assert_props_close(props_of(trimesh.creation.box((a, b, c)), rho), p, 1e-12)


def test_cylinder_against_tessellation_bounds():
    r, L, rho, n = 0.2, 0.5, 1200.0, 256
    mesh = trimesh.creation.cylinder(radius=r, height=L, sections=n)
    side = np.abs(mesh.face_normals[:, 2]) < 1e-12
    r_in = np.min(np.einsum("ij,ij->i", mesh.face_normals[side], mesh.triangles[side, 0]))
    assert r_in == pytest.approx(r * math.cos(math.pi / n), rel=1e-12)
    assert 1 - (r_in / r) ** 4 < 2e-3  # width of the bracket: ~4 (pi/n)^2 / 2 = 3e-4
    p = props_of(mesh, rho)
    lo, hi = mp.cylinder(r_in, L, rho), mp.cylinder(r, L, rho)
    assert_bracketed(lo.mass, p.mass, hi.mass)
    I0 = p.about_point(np.zeros(3))
    for k in range(3):
        assert_bracketed(lo.inertia[k, k], I0[k, k], hi.inertia[k, k])
    assert np.abs(p.inertia - np.diag(np.diag(p.inertia))).max() < 1e-12 * p.inertia[2, 2]


def test_capsule_against_tessellation_bounds():
    r, L, rho = 0.2, 0.5, 1200.0
    mesh = trimesh.creation.capsule(height=L, radius=r, count=[128, 128])
    assert mesh.bounds[1, 2] == pytest.approx(L / 2 + r)  # `height` is the cylinder part
    # inner capsule: largest radius around the axis segment inside every face plane
    n, v0 = mesh.face_normals, mesh.triangles[:, 0]
    r_in = min(np.min(np.einsum("ij,ij->i", n, v0 - e)) for e in ([0, 0, L / 2], [0, 0, -L / 2]))
    assert 0 < 1 - (r_in / r) ** 5 < 2e-3
    p = props_of(mesh, rho)
    lo, hi = mp.capsule(r_in, L, rho), mp.capsule(r, L, rho)
    assert_bracketed(lo.mass, p.mass, hi.mass)
    I0 = p.about_point(np.zeros(3))
    for k in range(3):
        assert_bracketed(lo.inertia[k, k], I0[k, k], hi.inertia[k, k])


@pytest.mark.parametrize("r, L", [(0.2, 0.5), (0.05, 1.0), (0.5, 0.1)])
def test_capsule_against_slice_integration(r, L):
    """Independent of the hemisphere algebra: integrate thin discs along the axis.

    A disc of radius a at height z, thickness dz: dm = rho pi a^2 dz,
    dI_zz = dm a^2 / 2, dI_xx = dm (a^2 / 4 + z^2).
    """
    rho = 900.0

    def a2(z):
        return r * r if abs(z) <= L / 2 else max(r * r - (abs(z) - L / 2) ** 2, 0.0)

    zmax = L / 2 + r
    pts = [-L / 2, L / 2]

    def integral(f):
        return quad(f, -zmax, zmax, points=pts, epsabs=0, epsrel=1e-13, limit=200)[0]

    m = integral(lambda z: rho * math.pi * a2(z))
    izz = integral(lambda z: rho * math.pi * a2(z) ** 2 / 2)
    ixx = integral(lambda z: rho * math.pi * a2(z) * (a2(z) / 4 + z * z))
    p = mp.capsule(r, L, rho)
    assert p.mass == pytest.approx(m, rel=1e-10)
    np.testing.assert_allclose(np.diag(p.inertia), [ixx, ixx, izz], rtol=1e-10)
    # and the two limits: no cylinder is a sphere, a thin cap is nearly a cylinder
    assert np.allclose(mp.capsule(r, 1e-12, rho).inertia, mp.sphere(r, rho).inertia, rtol=1e-9)


def test_with_mass_rescales():
    p = mp.capsule(0.1, 0.3, 1000.0)
    q = mp.with_mass(p, 2.5)
    assert q.mass == 2.5
    np.testing.assert_allclose(q.inertia, p.inertia * 2.5 / p.mass, rtol=1e-15)
    np.testing.assert_array_equal(q.com, p.com)
    c = mp.with_mass(mp.circle(0.2, 3.0), 4.0)
    assert c.moment == pytest.approx(0.5 * 4.0 * 0.04, rel=1e-14)
    with pytest.raises(ValueError):
        mp.with_mass(p, 0.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_invalid_dimensions_rejected(bad):
    for call in (lambda: mp.sphere(bad, 1.0), lambda: mp.box((1, bad, 1), 1.0),
                 lambda: mp.capsule(0.1, bad, 1.0), lambda: mp.cylinder(0.1, 0.2, bad),
                 lambda: mp.circle(bad, 1.0)):
        with pytest.raises(ValueError):
            call()


# ---------------------------------------------------------------------------------------------
# 2D
# ---------------------------------------------------------------------------------------------


def test_circle_and_box2d_closed_forms():
    c = mp.circle(0.3, 10.0)
    m = math.pi * 0.09 * 10.0
    assert c.mass == pytest.approx(m, rel=1e-15)
    assert c.moment == pytest.approx(0.5 * m * 0.09, rel=1e-15)
    b = mp.box2d((0.2, 0.6), 10.0)
    assert b.mass == pytest.approx(1.2, rel=1e-15)
    assert b.moment == pytest.approx(1.2 * (0.04 + 0.36) / 12, rel=1e-15)


def test_polygon_rectangle_both_orientations_offset_and_rotated():
    w, h, rho = 0.2, 0.6, 10.0
    ang, off = 0.7, np.array([3.0, -2.0])
    Rz = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
    rect = np.array([[-w / 2, -h / 2], [w / 2, -h / 2], [w / 2, h / 2], [-w / 2, h / 2]])
    verts = rect @ Rz.T + off
    ref = mp.box2d((w, h), rho)
    for v in (verts, verts[::-1]):
        p = mp.polygon(v, rho)
        assert p.mass == pytest.approx(ref.mass, rel=1e-12)
        np.testing.assert_allclose(p.com, off, rtol=0, atol=1e-12)
        assert p.moment == pytest.approx(ref.moment, rel=1e-10)


def test_polygon_fine_ngon_brackets_circle():
    r, rho, n = 0.3, 5.0, 720
    t = 2 * math.pi * np.arange(n) / n
    p = mp.polygon(np.c_[r * np.cos(t), r * np.sin(t)] + [1.0, 2.0], rho)
    r_in = r * math.cos(math.pi / n)  # inscribed n-gon: between the discs of r_in and r
    assert 1 - (r_in / r) ** 4 < 1e-4
    lo, hi = mp.circle(r_in, rho), mp.circle(r, rho)
    assert_bracketed(lo.mass, p.mass, hi.mass)
    assert_bracketed(lo.moment, p.moment, hi.moment, slack=1e-10)
    np.testing.assert_allclose(p.com, [1.0, 2.0], atol=1e-12)


def test_polygon_non_convex_l_against_two_rectangles():
    rho = 3.0
    p = mp.polygon(L_PROFILE, rho)
    parts = [(mp.box2d((0.3, 0.04), rho), [0.15, 0.02]), (mp.box2d((0.04, 0.16), rho),
                                                           [0.02, 0.12])]
    m = sum(q.mass for q, _ in parts)
    com = sum(q.mass * np.array(c) for q, c in parts) / m
    J = sum(q.moment + q.mass * float(np.sum((np.array(c) - com) ** 2)) for q, c in parts)
    assert p.mass == pytest.approx(m, rel=1e-13)
    np.testing.assert_allclose(p.com, com, rtol=1e-13)
    assert p.moment == pytest.approx(J, rel=1e-12)


def test_massprops2d_transforms():
    p = mp.polygon(L_PROFILE, 2.0)
    q = p.rotated(1.1).translated([0.5, -0.25])
    assert q.moment == p.moment
    assert q.about_point(q.com) == p.moment
    d = np.array([0.3, 0.4])
    assert p.about_point(p.com + d) == pytest.approx(p.moment + p.mass * 0.25, rel=1e-14)


# ---------------------------------------------------------------------------------------------
# polyhedral meshes
# ---------------------------------------------------------------------------------------------


def test_l_mesh_against_two_boxes_products_of_inertia():
    """Independent of trimesh: the L is two boxes; its x-z product of inertia is non-zero and its
    sign fixes the convention I_xz = -integral (x - x_c)(z - z_c) dm."""
    rho = 2700.0
    p = props_of(l_mesh(), rho)
    parts = [(mp.box((0.3, 0.1, 0.04), rho), [0.15, 0.05, 0.02]),
             (mp.box((0.04, 0.1, 0.16), rho), [0.02, 0.05, 0.12])]
    m = sum(q.mass for q, _ in parts)
    com = sum(q.mass * np.array(c) for q, c in parts) / m
    inertia = sum(mp.parallel_axis(q.inertia, q.mass, np.array(c) - com) for q, c in parts)
    assert p.mass == pytest.approx(m, rel=1e-13)
    np.testing.assert_allclose(p.com, com, rtol=1e-13)
    np.testing.assert_allclose(p.inertia, inertia, rtol=1e-12, atol=1e-14 * np.abs(inertia).max())
    # foot to the +x side at low z, upright at low x and high z: (x-xc)(z-zc) < 0 on average
    assert p.inertia[0, 2] > 0 and abs(p.inertia[0, 2]) > 0.1 * p.inertia[1, 1]
    assert p.inertia[0, 1] == pytest.approx(0, abs=1e-15) and abs(p.inertia[1, 2]) < 1e-15


def _trimesh_cases():
    rng = np.random.default_rng(12345)
    R = Rotation.random(3, random_state=7).as_matrix()
    return {
        "box offset rotated": transformed(trimesh.creation.box((0.1, 0.4, 0.9)), R[0],
                                          [3.0, -2.0, 5.0]),
        "torus offset rotated": transformed(trimesh.creation.torus(0.5, 0.15, 48, 24), R[1],
                                            [-1.0, 0.5, 2.0]),
        "L offset rotated": transformed(l_mesh(), R[2], rng.normal(size=3)),
        "l_bracket.obj": mp.load_mesh(L_BRACKET),
        "capsule": trimesh.creation.capsule(height=0.4, radius=0.1, count=[32, 32]),
    }


@pytest.mark.parametrize("name", list(_trimesh_cases()))
def test_mesh_matches_trimesh(name):
    mesh = _trimesh_cases()[name]
    assert mesh.is_volume
    rho = 1234.5
    p = props_of(mesh, rho)
    mesh.density = rho
    ref = mesh.mass_properties
    assert p.mass == pytest.approx(ref["mass"], rel=1e-9)
    assert p.mass == pytest.approx(rho * ref["volume"], rel=1e-9)
    scale = np.linalg.norm(mesh.extents)
    assert np.abs(p.com - ref["center_mass"]).max() <= 1e-9 * scale
    assert np.abs(p.inertia - ref["inertia"]).max() <= 1e-9 * np.abs(ref["inertia"]).max()
    if name.startswith(("L", "l_")):  # genuinely off-centre, non-aligned principal axes
        assert np.linalg.norm(p.com) > 0.05
        off = p.inertia - np.diag(np.diag(p.inertia))
        assert np.abs(off).max() > 0.1 * np.abs(p.inertia).max()


def test_mesh_rotation_and_translation_invariance():
    mesh = transformed(l_mesh(), np.eye(3), [0.3, -0.2, 0.1])
    p = props_of(mesh, 1000.0)
    for R in Rotation.random(4, random_state=3).as_matrix():
        q = props_of(transformed(mesh, R, [0, 0, 0]), 1000.0)
        expect = p.rotated(R)
        assert q.mass == pytest.approx(p.mass, rel=1e-13)
        np.testing.assert_allclose(q.com, R @ p.com, atol=1e-14)
        np.testing.assert_allclose(q.inertia, R @ p.inertia @ R.T, rtol=0,
                                   atol=1e-13 * np.abs(p.inertia).max())
        np.testing.assert_allclose(q.inertia, expect.inertia, rtol=0,
                                   atol=1e-13 * np.abs(p.inertia).max())
        # principal moments are invariant
        np.testing.assert_allclose(q.principal()[0], p.principal()[0], rtol=1e-12)
    t = np.array([10.0, -20.0, 30.0])
    q = props_of(transformed(mesh, np.eye(3), t), 1000.0)
    np.testing.assert_allclose(q.com, p.com + t, rtol=1e-13)
    np.testing.assert_allclose(q.inertia, p.inertia, rtol=0, atol=1e-11 * np.abs(p.inertia).max())
    np.testing.assert_allclose(p.translated(t).com, q.com, rtol=1e-13)


def test_inverted_mesh_rejected():
    mesh = l_mesh()
    with pytest.raises(ValueError, match="non-positive volume"):
        mp.mesh_mass_properties(mesh.vertices, mesh.faces[:, ::-1], 1000.0)


# ---------------------------------------------------------------------------------------------
# parallel axis, principal axes
# ---------------------------------------------------------------------------------------------


def test_parallel_axis_against_direct_sum_over_points():
    """For a cloud of equal point masses the inertia about any point is a direct sum; the
    parallel-axis theorem applied to the inertia about the centroid must reproduce it."""
    rng = np.random.default_rng(0)
    x = rng.normal(size=(500, 3)) * [0.3, 0.1, 0.2] + [1.0, -2.0, 0.5]
    mi = 0.01

    def about(o):
        r = x - o
        return mi * (np.sum(r * r) * np.eye(3) - r.T @ r)

    com = x.mean(axis=0)
    props = mp.MassProperties3D(mi * len(x), com, about(com))
    for p in (np.zeros(3), np.array([5.0, 1.0, -3.0]), com):
        np.testing.assert_allclose(props.about_point(p), about(p), rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(mp.parallel_axis(props.inertia, props.mass, p - com),
                                   about(p), rtol=1e-12, atol=1e-14)
    # sphere displaced along x: I_xx unchanged, I_yy = I_zz = 2/5 m r^2 + m d^2
    s = mp.sphere(0.1, 1000.0)
    Ip = s.about_point([0.5, 0, 0])
    np.testing.assert_allclose(np.diag(Ip), s.inertia[0, 0] + s.mass * np.array([0, .25, .25]))


def test_principal_reconstructs_and_is_proper_rotation():
    mats = [props_of(mp.load_mesh(L_BRACKET), 2700.0)]
    for R in Rotation.random(5, random_state=11).as_matrix():
        mats.append(mp.MassProperties3D(1.0, np.zeros(3), R @ np.diag([1.0, 2.0, 2.5]) @ R.T))
    mats.append(mp.sphere(0.2, 10.0))  # degenerate: all moments equal
    mats.append(mp.cylinder(0.2, 0.3, 10.0))  # two equal moments
    for p in mats:
        moments, axes = p.principal()
        assert np.all(np.diff(moments) >= 0)
        np.testing.assert_allclose(axes.T @ axes, np.eye(3), atol=1e-13)
        assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-13)
        np.testing.assert_allclose(axes @ np.diag(moments) @ axes.T, p.inertia,
                                   atol=1e-13 * np.abs(p.inertia).max())
        # triangle inequality of principal moments of any real body
        assert moments[0] + moments[1] >= moments[2] * (1 - 1e-12)


def test_rotated_is_congruence():
    p = props_of(mp.load_mesh(L_BRACKET), 2700.0)
    R = Rotation.from_euler("zyx", [10, 20, 30], degrees=True).as_matrix()
    q = p.rotated(R)
    np.testing.assert_allclose(q.com, R @ p.com)
    np.testing.assert_allclose(q.inertia, R @ p.inertia @ R.T, atol=1e-16)
    np.testing.assert_allclose(q.rotated(R.T).inertia, p.inertia, atol=1e-16)


# ---------------------------------------------------------------------------------------------
# bounding box, point sampling, inside test
# ---------------------------------------------------------------------------------------------


def test_bounding_box_exact_on_axis_aligned_box():
    size, c = np.array([0.1, 0.4, 0.9]), np.array([1.0, 2.0, -3.0])
    mesh = transformed(trimesh.creation.box(size), np.eye(3), c)
    bb = mp.bounding_box_mass_properties(mesh.vertices, 500.0)
    exact = props_of(mesh, 500.0)
    assert_props_close(bb, exact, 1e-12)
    assert_props_close(bb, mp.box(size, 500.0).translated(c), 1e-12)
    bm = mp.bounding_box_mass_properties(mesh.vertices, mass=3.0)
    np.testing.assert_allclose(bm.inertia, exact.inertia * 3.0 / exact.mass, rtol=1e-12,
                               atol=1e-15)
    with pytest.raises(ValueError):
        mp.bounding_box_mass_properties(mesh.vertices)
    with pytest.raises(ValueError):
        mp.bounding_box_mass_properties(mesh.vertices, 1.0, mass=1.0)


def test_bounding_box_is_poor_on_l_bracket():
    mesh = mp.load_mesh(L_BRACKET)
    exact = props_of(mesh, 2700.0)
    bb = mp.bounding_box_mass_properties(mesh.vertices, 2700.0)
    assert bb.mass > 5 * exact.mass  # the seeds' "bounding box may not be a good fit"
    assert np.abs(bb.inertia - np.diag(np.diag(bb.inertia))).max() == 0.0


def test_points_inside_against_analytic_shapes():
    rng = np.random.default_rng(1)
    R = Rotation.random(random_state=2).as_matrix()
    size = np.array([0.3, 0.5, 0.7])
    mesh = transformed(trimesh.creation.box(size), R, [0.1, 0.2, 0.3])
    pts = rng.uniform(-0.6, 0.9, size=(20000, 3))
    local = (pts - [0.1, 0.2, 0.3]) @ R  # R^T (p - t)
    expect = np.all(np.abs(local) < size / 2, axis=1)
    np.testing.assert_array_equal(mp.points_inside(mesh.triangles, pts), expect)
    # torus (non-convex, genus 1): rays cross the surface 0, 2 or 4 times; compare away from
    # the tessellation error band
    R0, r0 = 0.5, 0.15
    tor = trimesh.creation.torus(R0, r0, 64, 32)
    pts = rng.uniform(-0.7, 0.7, size=(20000, 3))
    dist = np.hypot(np.hypot(pts[:, 0], pts[:, 1]) - R0, pts[:, 2])
    clear = np.abs(dist - r0) > 0.01
    got = mp.points_inside(tor.triangles, pts)
    np.testing.assert_array_equal(got[clear], (dist < r0)[clear])


def test_points_inside_on_shared_edges_and_vertices():
    """Rays through projected edges and vertices of an axis-aligned cube are counted once."""
    mesh = trimesh.creation.box((1.0, 1.0, 1.0))  # faces split along diagonals
    g = np.linspace(-0.25, 0.25, 5)  # passes through x = y diagonals and the centre vertex
    pts = np.array([(x, y, 0.0) for x in g for y in g] + [(0.0, 0.0, -0.49), (0.3, -0.3, 0.1)])
    assert mp.points_inside(mesh.triangles, pts).all()
    assert not mp.points_inside(mesh.triangles, pts + [0, 0, 1.0]).any()


def test_sampling_deterministic_and_accurate():
    mesh = mp.load_mesh(L_BRACKET)
    a = mp.sampled_mass_properties(mesh, 2700.0, 20000, seed=5)
    b = mp.sampled_mass_properties(mesh, 2700.0, 20000, seed=5)
    c = mp.sampled_mass_properties(mesh, 2700.0, 20000, seed=6)
    assert a.mass == b.mass
    np.testing.assert_array_equal(a.inertia, b.inertia)
    assert not np.array_equal(a.inertia, c.inertia)


def test_sampling_converges_like_inverse_sqrt_n():
    """RMS errors over 6 seeds at N = 1e3 and 1e5: ideally in ratio sqrt(100) = 10. The bound
    3 < ratio < 33 fails for a biased estimator (ratio -> 1) and for a wrong inside test."""
    mesh = mp.load_mesh(L_BRACKET)
    rho = 2700.0
    exact = props_of(mesh, rho)

    def rms_errors(n):
        e = []
        for seed in range(6):
            s = mp.sampled_mass_properties(mesh, rho, n, seed)
            e.append([abs(s.mass / exact.mass - 1),
                      np.linalg.norm(s.inertia - exact.inertia) / np.linalg.norm(exact.inertia)])
        return np.sqrt(np.mean(np.square(e), axis=0))

    coarse, fine = rms_errors(1_000), rms_errors(100_000)
    ratio = coarse / fine
    assert np.all((ratio > 3) & (ratio < 33)), (coarse, fine)
    # the inside fraction is ~9 %: sigma(mass) ~ sqrt((1-p)/(p N)) ~ 1e-2 at N = 1e5
    assert fine[0] < 0.03 and fine[1] < 0.05, fine


# ---------------------------------------------------------------------------------------------
# loading and bad input
# ---------------------------------------------------------------------------------------------


def test_load_l_bracket():
    mesh = mp.load_mesh(L_BRACKET)
    assert L_BRACKET.stat().st_size < 50_000
    p = props_of(mesh, 2700.0)
    assert p.mass == pytest.approx(2700.0 * 0.1 * (0.3 * 0.04 + 0.04 * 0.16), rel=1e-12)
    assert np.linalg.norm(p.com) > 0.1


def test_open_mesh_rejected():
    with pytest.raises(mp.MeshError, match="watertight") as err:
        mp.load_mesh(NOT_CLOSED)
    assert str(err.value).startswith(str(NOT_CLOSED))
    mesh = mp.load_mesh(NOT_CLOSED, check=False)
    with pytest.raises(mp.MeshError, match="closed, consistently oriented"):
        mp.check_closed_volume(mesh)
    with pytest.raises(mp.MeshError):  # parity is meaningless for an open surface
        mp.sampled_mass_properties(mesh, 1000.0, 100)


def test_missing_and_garbage_files_rejected(tmp_path):
    missing = tmp_path / "nope.obj"
    with pytest.raises(mp.MeshError, match="not found") as err:
        mp.load_mesh(missing)
    assert err.value.path == str(missing)
    assert isinstance(err.value, ValueError)
    garbage = tmp_path / "garbage.obj"
    garbage.write_text("this is not a mesh\n")
    with pytest.raises(mp.MeshError, match="watertight"):
        mp.load_mesh(garbage)
    odd = tmp_path / "mesh.unknownext"
    odd.write_text("v 0 0 0\n")
    with pytest.raises(mp.MeshError, match="cannot read"):
        mp.load_mesh(odd)


def test_inverted_mesh_file_rejected(tmp_path):
    mesh = l_mesh()
    mesh.faces = mesh.faces[:, ::-1]
    path = tmp_path / "inverted.obj"
    mesh.export(path)
    with pytest.raises(mp.MeshError, match="positive volume"):
        mp.load_mesh(path)
