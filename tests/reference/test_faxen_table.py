"""The Faxen (1946) wall factor table against its public copy (issue 14, point 2).

reference/data/faxen1946_cylinder_between_plates.csv keeps the series as usually quoted, through
k^8; one public copy (PhysBAM's 2D solid-fluid standard tests, citing Wang and Liu 2004; the file's
header has the details) carries it through k^4. These tests pin the agreement term by term and
the weight of the two terms no copy checks, at the sedimentation case's k = 0.25."""

import math

from crosscheck.reference.fluid_data import (
    faxen_channel_lambda,
    faxen_settling_velocity,
    load_table,
)

# Copy 1 (PhysBAM STANDARD_TESTS.h, Falling_Rigid_Circle_Test): ln(1/k) - 0.9157 + 1.7244 k^2
# - 1.7302 k^4, and U = (rho_s - rho) g r^2 Lambda / (4 mu).
COPY_1 = {0: -0.9157, 2: 1.7244, 4: -1.7302}


def test_the_table_agrees_with_the_public_copy_term_by_term():
    table = load_table("faxen_1946")
    coeffs = dict(zip(table["power"].astype(int), table["coefficient"], strict=True))
    for power, value in COPY_1.items():
        assert coeffs[power] == value
    assert sorted(coeffs) == [0, 2, 4, 6, 8]   # k^6 and k^8: no copy found


def test_the_unchecked_terms_weigh_under_a_thousandth_at_the_case_k():
    k = 0.25
    full = faxen_channel_lambda(k)
    checked = math.log(1.0 / k) + sum(c * k ** p for p, c in COPY_1.items())
    assert abs(full - 0.572128) < 5e-7 and abs(checked - 0.571611) < 5e-7
    assert 0.0 < full / checked - 1.0 < 1e-3          # +0.090 %


def test_the_copy_prefactor_gives_the_case_speed():
    # cases/fluid/sedimentation_channel.toml: a = 0.1, h = 0.4, rho_s = 5000, rho = 1000, nu = 0.5
    u = faxen_settling_velocity(0.1, 0.4, 5000.0, 1000.0, 0.5, 9.81)
    lam = faxen_channel_lambda(0.25)
    assert math.isclose(u, (5000.0 - 1000.0) * 9.81 * 0.1 ** 2 * lam / (4 * 1000.0 * 0.5))
    assert abs(u - 0.11225) < 5e-6
