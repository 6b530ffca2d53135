"""crosscheck.warmup (the numba warm-up the top-level conftest runs before pytest-xdist's
workers): every cell of the case files is in exactly one part, and the 3D detection's users are
ordered so that only one part compiles it first."""

from __future__ import annotations

from crosscheck import warmup


def test_every_cell_is_warmed_by_exactly_one_part():
    cells = warmup.cells()
    families = [f for f, *_ in cells]
    for n in (1, 2, 3):
        parts = warmup.split(families, n)
        assert len(parts) == n
        flat = [f for p in parts for f in p]
        assert len(flat) == len(set(flat))
        assert set(families) <= set(flat)
    assert {"3d-velocity", "2d-velocity", "fluid", "native"} <= set(families)
    assert {engine for _, _, engine, *_ in cells} == {"inhouse", *warmup.NATIVE}


def test_two_parts_keep_the_3d_detection_to_the_first_part_until_its_end():
    first, second = warmup.split([f for f, *_ in warmup.cells()], 2)
    assert first[0] == "3d-velocity"
    # the second part's only user of the 3D detection comes last
    assert second[-1] == "3d-penalty"
    assert not {"3d-velocity", "3d-impulse_lcp"} & set(second)
