"""The in-house registry binds a kernel to every name crosscheck.names lists for the in-house
engine, and nothing else: a name without a kernel, or a kernel without a name, fails here (it
used to make the conformance suite skip)."""

from __future__ import annotations

import pytest

from crosscheck import names
from crosscheck.sim.rigid import integrators as reg


def test_every_listed_name_has_kernels_in_order():
    assert tuple(reg.INTEGRATORS) == names.rigid_names("inhouse")
    assert reg.DEFAULT == names.rigid_names("inhouse")[0]
    for name, integ in reg.INTEGRATORS.items():
        info = names.integrator_info("inhouse", name)
        assert (integ.order, integ.symplectic, integ.scheme, integ.contact) == \
            (info.order, info.symplectic, info.scheme, info.contact)
        assert callable(integ.advance3d) and callable(integ.advance2d), name
        for fn in (integ.advance3d, integ.advance2d):
            kernel = getattr(fn, "kernel", fn)
            assert callable(kernel), name


def test_a_kernel_without_a_name_is_refused():
    with pytest.raises(KeyError, match="no rigid-body integrator 'rk5'"):
        reg.bind("rk5", "exp", 5, "", lambda *a: None, lambda *a: None)
    assert "rk5" not in reg.INTEGRATORS


def test_a_name_bound_twice_is_refused():
    with pytest.raises(ValueError, match="already registered"):
        reg.bind("rk4", "exp", 4, "", lambda *a: None, lambda *a: None)


def test_fluid_schemes_are_not_rigid_integrators():
    assert not set(names.fluid_names("inhouse")) & set(reg.INTEGRATORS)
