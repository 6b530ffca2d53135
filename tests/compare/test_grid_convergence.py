"""The three-grid procedure (compare/grid_convergence.py) against the procedure's own worked
example and against sequences whose limit and order are known exactly."""

import math

import pytest

from crosscheck.compare.grid_convergence import grid_sequence, three_grids


def test_celik_et_al_worked_example():
    # Celik et al. (2008), Table 1, first column (a reattachment length on 18000 / 8000 / 4500
    # cells in 2D, h = N^(-1/2)), as a public copy states it: the tests of
    # tomrobin-teschner/pyGCS (tests/test_GCI.py, commit 04e28c3b), whose bounds are the
    # table's printed p = 1.53, phi_ext = 6.1685, GCI_fine = 2.2 % and the coarse pair's index
    h = tuple(n ** -0.5 for n in (18000, 8000, 4500))
    t = three_grids(h, (6.063, 5.972, 5.863))
    assert t.kind == "monotone"
    assert 1.53 < t.order < 1.54
    assert t.limit == pytest.approx(6.1685, abs=5e-5)
    assert 0.0217 < t.gci_fine < 0.0218
    assert 0.0411 < t.gci_coarse < 0.0412


@pytest.mark.parametrize("order", [0.7, 1.0, 1.7, 2.0, 3.2])
def test_a_power_law_is_recovered_exactly_whatever_the_ratios(order):
    # f0 + C h^p on the uneven sequence of the sedimentation study (ratios 1.5 down to 1.14):
    # every triple must give the same order and limit, to the root finder's tolerance
    cells = [16, 24, 32, 40, 48, 56, 64]
    h = [1.0 / c for c in cells]
    f = [2.0988 - 3.1 * x ** order for x in h]
    triples = grid_sequence(h, f)
    assert len(triples) == len(cells) - 2
    for t in triples:
        assert t.kind == "monotone"
        assert t.order == pytest.approx(order, abs=1e-8)
        assert t.limit == pytest.approx(2.0988, abs=1e-11)
        # the index bounds the fine grid's true distance from the limit by the safety factor
        true = abs(t.f[0] - 2.0988) / abs(t.f[0])
        assert t.gci_fine == pytest.approx(1.25 * true, rel=1e-8)


def test_two_orders_mixed_show_the_triples_disagreeing():
    # f0 + h + 10 h^2, the two terms equal at h = 0.1: the coarse triples read near 2, the
    # fine ones fall toward 1 (1.72 / 1.57 / 1.40 / 1.25 / 1.14 here); the sequence shows the
    # grids outside the asymptotic range, where each triple alone would give a plausible order
    h = [1.0 / c for c in (4, 8, 16, 32, 64, 128, 256)]
    f = [1.0 + x + 10.0 * x * x for x in h]
    orders = [t.order for t in grid_sequence(h, f)]
    assert orders == sorted(orders, reverse=True)
    assert orders[0] > 1.7 and orders[-1] < 1.2


def test_what_has_no_limit_gets_none():
    h = (1.0 / 4, 1.0 / 2, 1.0)
    osc = three_grids(h, (1.0, 1.1, 0.8))
    assert osc.kind == "oscillatory" and osc.limit is None and osc.gci_fine is None
    assert osc.order > 0
    grow = three_grids(h, (1.0, 1.3, 1.4))            # the finer pair differs more
    assert grow.kind == "divergent" and grow.order is None and grow.limit is None
    # uneven ratios: e21 / e32 must stay below ln r21 / ln r32 for a positive order; just
    # below it the order is small and positive, just above there is none
    uneven = (1.0 / 64, 1.0 / 48, 1.0 / 24)            # r21 = 1.33, r32 = 2
    ceiling = math.log(64 / 48) / math.log(2)
    above = three_grids(uneven, (0.0, 1.05 * ceiling, 1.05 * ceiling + 1.0))
    assert above.kind == "divergent" and above.order is None
    below = three_grids(uneven, (0.0, 0.95 * ceiling, 0.95 * ceiling + 1.0))
    assert below.kind == "monotone" and 0.0 < below.order < 0.2
    same = three_grids(h, (2.0, 2.0, 2.5))
    assert same.kind == "converged" and same.limit == 2.0 and same.gci_fine == 0.0
    # a finer pair that has stopped changing (an order past 64) is converged, not divergent
    flat = three_grids((1.0 / 56, 1.0 / 48, 1.0 / 40), (2.0, 2.0 + 1e-9, 2.1))
    assert flat.kind == "converged" and flat.limit == 2.0 and flat.order is None


def test_the_grids_must_be_given_in_order():
    with pytest.raises(ValueError, match="increase"):
        three_grids((0.5, 0.25, 1.0), (1.0, 1.1, 1.2))
    with pytest.raises(ValueError, match="3 spacings against 2 values"):
        grid_sequence([1.0, 0.5, 0.25], [1.0, 1.1])
