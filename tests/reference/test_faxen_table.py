"""The Faxen (1946) wall factor table against its public copies and the Stokes equations
(issue 14, point 3).

reference/data/faxen1946_cylinder_between_plates.csv keeps the series as usually quoted, through
k^8. Two independent public copies (the file's header has the details): PhysBAM's 2D solid-fluid
standard tests (citing Wang and Liu 2004), through k^4, and a lattice Boltzmann settling code
(lalwdl/LBM-Fluid-Structure-Interaction), through k^8. They agree with the file on every
coefficient but the constant, where the second has 0.9175 for 0.9157; the constant and the k^2
term are computed here from the Stokes equations, which settles it. These tests pin the
agreement term by term and the weight of the terms fewer copies carry, at the sedimentation
case's k = 0.25."""

import math

from crosscheck.reference.fluid_data import (
    faxen_channel_lambda,
    faxen_settling_velocity,
    load_table,
)

# Copy 1 (PhysBAM STANDARD_TESTS.h, Falling_Rigid_Circle_Test): ln(1/k) - 0.9157 + 1.7244 k^2
# - 1.7302 k^4, and U = (rho_s - rho) g r^2 Lambda / (4 mu).
COPY_1 = {0: -0.9157, 2: 1.7244, 4: -1.7302}
# Copy 2 (lalwdl/LBM-Fluid-Structure-Interaction, 2-particle.cpp, init(), with W_ = 1 / k):
# 1 / (log(W_) - 0.9175 + 1.7244 W_^-2 - 1.7302 W_^-4 + 2.4056 W_^-6 - 4.5913 W_^-8)
COPY_2 = {0: -0.9175, 2: 1.7244, 4: -1.7302, 6: 2.4056, 8: -4.5913}


def _coefficients():
    table = load_table("faxen_1946")
    return dict(zip(table["power"].astype(int), table["coefficient"], strict=True))


def test_the_table_agrees_with_the_public_copies_term_by_term():
    coeffs = _coefficients()
    assert sorted(coeffs) == [0, 2, 4, 6, 8]
    for power, value in COPY_1.items():
        assert coeffs[power] == value
    for power in (2, 4, 6, 8):
        assert coeffs[power] == COPY_2[power]
    # the constant: the copies differ by a transposed digit; the Stokes equations decide below
    assert COPY_2[0] != coeffs[0] == COPY_1[0]


def test_the_terms_one_copy_carries_weigh_under_a_thousandth_at_the_case_k():
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


# -- the first two coefficients from the Stokes equations themselves ----------------------------
# A line force F (per unit length, along the walls) midway between no-slip walls at y = +-h: the
# stream function's Fourier transform in x, psi(alpha, y), solves mu (d2/dy2 - alpha^2)^2 psi =
# -F delta'(y); the free-space part is (F / mu) y exp(-|alpha| |y|) / (4 |alpha|), the walls add
# the odd solution C sinh(alpha y) + D y cosh(alpha y) that makes psi and psi' vanish at y = h.
# The cylinder of radius a is the line force plus the potential doublet (F a^2 / 8 pi mu)
# grad(x / r^2), whose velocity on r = a is uniform (the classical Stokeslet-plus-doublet solution
# for a translating circle, checked term by term on r = a). Its velocity between the
# walls, to O(a^2): the free-space value, plus the walls' field at the centre averaged over the
# circle (the mean value of a Stokes velocity over a circle is u + a^2/4 lap u), plus the walls'
# reflection of the doublet. Lambda = 4 pi mu U / F then gives the constant and the k^2 term.

def _wall_solution(alpha, psi_h, dpsi_h, h=1.0):
    """(C, D) of C sinh(alpha y) + D y cosh(alpha y) cancelling psi and psi' at y = h."""
    import numpy as np

    s, c = np.sinh(alpha * h), np.cosh(alpha * h)
    return np.linalg.solve([[s, h * c], [alpha * c, c + alpha * h * s]], [-psi_h, -dpsi_h])


def _faxen_constant_and_k2():
    from scipy.integrate import quad

    def stokeslet(alpha):          # F / mu = 1, h = 1
        e = math.exp(-alpha)
        return _wall_solution(alpha, e / (4 * alpha), (1 - alpha) * e / (4 * alpha))

    def doublet(alpha):   # unit u = grad(x / r^2): psi = -y / r^2, transform -pi e^(-alpha y)
        e = math.exp(-alpha)
        return _wall_solution(alpha, -math.pi * e, math.pi * alpha * e)

    # the walls' velocity at the centre, alpha^-1 subtracted below alpha = 1 (the regularisation
    # in which the free Stokeslet's velocity along its axis is (F / 4 pi mu)(-ln r - gamma))
    def at_centre(alpha):
        c, d = stokeslet(alpha)
        return c * alpha + d + (0.25 / alpha if alpha < 1.0 else 0.0)

    reg = (quad(at_centre, 0.0, 1.0, limit=200, epsabs=1e-13)[0]
           + quad(at_centre, 1.0, 40.0, limit=200, epsabs=1e-13)[0]) / math.pi
    # free cylinder in that regularisation: U = (F / 4 pi mu)(ln(1/a) - 1/2 - gamma)
    constant = 0.5 + 0.5772156649015329 - 4.0 * math.pi * reg
    # O(a^2): lap of the walls' Stokeslet field at the centre is (1/pi) int 2 D alpha^2, and the
    # doublet's reflection (1/pi) int (C alpha + D), strength a^2 / 8 pi
    lap = quad(lambda a: 2.0 * stokeslet(a)[1] * a * a, 1e-9, 40.0, limit=400,
               epsabs=1e-13)[0] / math.pi
    refl = quad(lambda a: doublet(a)[0] * a + doublet(a)[1], 1e-9, 40.0, limit=400,
                epsabs=1e-13)[0] / math.pi
    k2 = 4.0 * math.pi * (0.25 * lap + refl / (8.0 * math.pi))
    return constant, k2


def test_the_constant_and_k2_term_follow_from_the_stokes_equations():
    """The two public copies of the series disagree on the constant (0.9157 in PhysBAM's, 0.9175
    in lalwdl/LBM-Fluid-Structure-Interaction's; the file's header): computed here from the
    Stokes equations between the walls it is 0.915689, and the k^2 coefficient 1.724384, the
    file's values to their four decimals. A transposed digit (0.9175) is 1.8e-3 off and fails."""
    constant, k2 = _faxen_constant_and_k2()
    coeffs = _coefficients()
    assert abs(-coeffs[0] - constant) < 5e-5, constant
    assert abs(coeffs[2] - k2) < 5e-5, k2
