"""Wachs's (2009, fig. 5a) published path of the settling disc (src/crosscheck/reference/data/
wachs2009_fig5a_path.csv, a digitisation of the figure): it starts where the benchmark releases
the disc and ends swinging about the axis, and the numbers its header and docs/fluid.md quote
are what :func:`wachs_path_offsets` reads from it."""

import pytest

from crosscheck.reference.fluid_data import (
    WACHS_PATH_AXIS,
    WACHS_PATH_RELEASE,
    wachs_path,
    wachs_path_offsets,
)


@pytest.mark.parametrize("ratio", [1.5, 3.0])
def test_the_path_starts_at_the_release_and_ends_about_the_axis(ratio):
    """Both density ratios: the top of the path within 0.02 d of the release line (1 d off the
    axis) and within 1.2 d below the release height the header infers (40); over the last 30 d
    the mean within 0.03 d of the axis (0.008 at r = 1.5, 0.026 at r = 3) and every point within
    0.2 d of it (0.11 and 0.15): a swing about the axis, not a drift towards a wall."""
    x, y = wachs_path(ratio)
    assert (y[:-1] > y[1:]).all()                      # a function x(y), falling
    assert abs(x[0] - WACHS_PATH_RELEASE[0]) < 0.02
    assert 0.0 < WACHS_PATH_RELEASE[1] - y[0] < 1.2
    late = y < y[-1] + 30.0
    assert abs(x[late].mean() - WACHS_PATH_AXIS) < 0.03
    assert abs(x[late] - WACHS_PATH_AXIS).max() < 0.2


def test_the_quoted_offsets_are_the_paths():
    """r = 1.5 over the gate case's stretch of the fall (14.7 to 39.7 d below the release): the
    largest distance from the axis 0.220 d (the swing back after the disc's first overshoot), the
    mean 0.073 d; farther down (40 to 95 d) 0.116 and 0.064, an amplitude of about 0.1 d. A
    stretch beyond the digitised path is not measured."""
    assert wachs_path_offsets(1.5, 14.7, 39.7) == pytest.approx((0.220, 0.073), abs=1e-3)
    assert wachs_path_offsets(1.5, 40.0, 95.0) == pytest.approx((0.116, 0.064), abs=1e-3)
    assert wachs_path_offsets(1.5, 14.7, 120.0) is None
    assert wachs_path_offsets(1.5, 0.5, 10.0) is None          # above the first digitised point
    with pytest.raises(KeyError):
        wachs_path(2.0)
