"""The numba options and cache stamp of the in-house kernels live in :mod:`crosscheck.sim._jit`
(shared with sim/collide, whose functions the contact models inline); this name stays importable
for code written against it."""

from crosscheck.sim._jit import INLINE, JIT, LOCATORS_REGISTERED, package_sources, package_stamp

__all__ = ["INLINE", "JIT", "LOCATORS_REGISTERED", "package_sources", "package_stamp"]
