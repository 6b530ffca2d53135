"""The heave table of a half-immersed circle (data/ursell1949_semicircle_heave.csv) against its
second public copy, and the natural period built on it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crosscheck.reference.fluid_data import floating_circle_heave, load_table, ursell_heave


def _faltinsen_fit(k):
    """pciuh/hydcoef's fits to Faltinsen's graph (the table's header): a33 / (rho A) and
    b33 / (rho A omega)."""
    return (0.31969453 * np.exp(0.60779994 * k) / k ** 0.59697270,
            2.31912227 * np.exp(-1.85300997 * k ** 0.76217309))


def test_two_copies_agree_where_a_floating_circle_heaves():
    """Added mass within 2 % at k = 0.5-0.9, 3 % at 1.0 and 5.05 % at 1.2; damping 4-10 % below
    (the fit to a graph). A table whose damping column were b33 / (rho A omega) instead (off by
    sqrt(k)) would miss the fit by 17-26 % at k = 0.6-0.8."""
    t = load_table("ursell_1949")
    k = t["K"]
    a_fit, b_fit = _faltinsen_fit(k)
    a_rel = a_fit / t["added_mass"] - 1.0
    b_rel = b_fit / (t["damping"] / np.sqrt(k)) - 1.0
    near = k <= 0.9
    assert np.max(np.abs(a_rel[near])) < 0.02
    assert np.max(np.abs(a_rel)) < 0.055
    assert np.all((b_rel < -0.03) & (b_rel > -0.10))
    assert t.source and any("Ursell" in line for line in t.source)


def test_natural_period_solves_its_own_frequency():
    """omega^2 (M + a33(omega)) = C at the period returned, for M = rho pi R^2 / 2 and
    C = 2 rho g R, and it lies between the periods with no added mass and with the
    high-frequency limit a33 = M."""
    r, g = 0.08, 9.81
    period, ratio = floating_circle_heave(r, g)
    omega = 2 * math.pi / period
    k = omega ** 2 * r / g
    added, damping = ursell_heave(k)
    mass = math.pi * r ** 2 / 2                       # per unit rho
    assert omega ** 2 * mass * (1 + added) == pytest.approx(2 * g * r, rel=1e-9)
    assert 2 * math.pi * math.sqrt(mass / (2 * g * r)) < period
    assert period < 2 * math.pi * math.sqrt(2 * mass / (2 * g * r))
    b = damping * mass * math.sqrt(g / r)
    assert ratio == pytest.approx(b / (2 * math.sqrt(2 * g * r * mass * (1 + added))), rel=1e-12)
    with pytest.raises(ValueError, match="omega"):
        ursell_heave(2.0)
