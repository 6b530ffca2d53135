"""Wachs's (2009) disc settling in a channel four diameters wide (issue 14, point 3): the file
parses and its two published numbers agree with each other through the force balance.

reference/data/wachs2009_disc_channel_sedimentation.csv quotes the terminal Reynolds number and
drag coefficient from one public copy (its header names it). At terminal speed the fluid carries
the reduced weight, so C_D = (r - 1) g pi d / (2 U^2) with U = Re nu / d: a misread digit in
either number would break it."""

import math

import pytest

from crosscheck.reference.fluid_data import (
    WACHS_2009,
    galileo_number,
    settling_drag_coefficient,
    wachs_sedimentation,
)

WACHS_G, WACHS_NU = WACHS_2009["g"], WACHS_2009["nu"]


@pytest.mark.parametrize("ratio", [1.5, 3.0])
def test_published_drag_balances_the_reduced_weight_at_the_published_reynolds(ratio):
    b = wachs_sedimentation(ratio)
    u = b.reynolds * WACHS_NU / 1.0
    cd = settling_drag_coefficient(ratio, WACHS_G, 1.0, u)
    # Re is quoted to four figures (+-0.05 / 259.5 = 2e-4 -> 4e-4 in C_D): measured -0.12 %
    # and -0.09 %, i.e. C_D rounded from a slightly lower Re (259.35 and 521.8)
    assert abs(cd / b.drag_coefficient - 1.0) < 2e-3


def test_the_benchmark_groups():
    b = wachs_sedimentation(1.5)
    assert (b.reynolds, b.drag_coefficient, b.width_ratio) == (259.5, 1.785, 4.0)
    assert math.isclose(b.galileo, math.sqrt(0.5 * 10.0) / 0.008088)
    assert abs(b.galileo - 276.47) < 0.01
    # (r - 1) four times as large at r = 3: Ga doubles
    assert math.isclose(galileo_number(3.0, WACHS_G, 1.0, WACHS_NU), 2.0 * b.galileo)
    assert any("Basilisk" in line for line in b.source)   # the copy is named in the header


def test_the_loader_s_catalogue_is_the_file_s_rows():
    """The loader checks a case against WACHS_2009 (below reference/, without reading the file):
    its density ratios must be the file's rows."""
    for r in WACHS_2009["density_ratios"]:
        assert wachs_sedimentation(r).density_ratio == r


def test_an_unpublished_density_ratio_is_refused():
    with pytest.raises(KeyError):
        wachs_sedimentation(2.0)
