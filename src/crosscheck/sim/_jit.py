"""numba options of the in-house kernels, and one cache stamp for all of their modules.

The kernels are split by job (sim/rigid: math3d; forces3d / forces2d; explicit3d / explicit2d,
the Runge-Kutta family; splitting3d / splitting2d, the symplectic family; implicit; sim/collide:
the collision detection the contact models of sim/rigid call) and call, and inline, each
other's functions across modules and across the two packages. numba's on-disk cache
(``cache=True``) stamps a function's cached machine code with the hash of *its own* source file
only, so after an edit to a helper in math3d.py the cached RK4 step of explicit3d.py, which
carries its own copy of the helper, would be loaded unchanged: stale code, silently. This module
therefore registers cache
locators for the files of the stamped packages (:data:`PACKAGE_DIRS`: sim/rigid and sim/collide)
whose source stamp is the hash of *every* ``.py`` file in them: an edit anywhere in either package
recompiles every kernel of both (once; about a minute for everything tests/rigid uses), never a
stale one. They mirror numba's own two first locators (``NUMBA_CACHE_DIR`` when set, else
``__pycache__`` next to the source) and take only files of those packages; every other file
(sim/fluid included) keeps numba's default locators. Import this module before any kernel is
decorated (every kernel module imports JIT / INLINE from here).
"""

from __future__ import annotations

import hashlib
import os

# error_model="numpy": a division by zero gives inf/nan (a blow-up the driver reports), never a
# Python exception from inside a step. No fastmath: IEEE semantics keep NaN checks valid and
# results bit-identical from run to run.
JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
# Helpers called per body or per spring (and the effect kernels inside ``evaluate``) are inlined
# at numba's IR level: a call between compiled functions pays atomic reference counting on every
# array argument (measured: 145 ns per spring evaluation as a call, 19 ns inlined). ``evaluate``
# itself stays a call, once per stage: it is then compiled once per effect set and shared by all
# integrators, which halves the cold-cache compile time (72 s instead of 145 s for tests/rigid)
# for a few percent at N = 1.
INLINE = dict(JIT, inline="always")
# Literal arguments. A compiled function that calls a JIT function with an argument numba types
# as a literal (a counter that starts at ``0``, a ``True`` / ``False`` flag) compiles the callee
# once for the literal's type, and again for int64 once the counter's loop widens it: numba
# resolves the call before it unifies the counter's type. Each is a second compile of the
# callee's whole tree (30 s for impulse_lcp.solve3d, measured). Counters handed to kernels
# therefore start as ``np.int64(0)`` and mode flags are passed as ``np.bool_(...)``.

SIM_DIR = os.path.dirname(os.path.abspath(__file__))
# The packages whose kernels call each other: the contact models of sim/rigid inline the
# collision functions of sim/collide, so both share one stamp.
PACKAGE_DIRS = (os.path.join(SIM_DIR, "rigid"), os.path.join(SIM_DIR, "collide"))


def package_sources() -> list[str]:
    """The files whose content the kernels' cache stamp covers: every .py file of the stamped
    packages, in a fixed order."""
    return sorted(os.path.join(d, f) for d in PACKAGE_DIRS for f in os.listdir(d)
                  if f.endswith(".py"))


def package_stamp() -> bytes:
    """sha256 over the packages' source files (package and file names, contents); numba memoises
    each file's hash by (path, mtime, size), so this costs a stat per file once the hashes are
    known."""
    from numba.core.caching import _hash_source_file

    digest = hashlib.sha256()
    for path in package_sources():
        st = os.stat(path)
        digest.update(os.path.relpath(path, SIM_DIR).encode())
        digest.update(_hash_source_file(path, st.st_mtime, st.st_size))
    return digest.digest()


def _register_locators() -> bool:
    """Put the package-stamped locators first in numba's list; False if numba's caching
    internals are not what this expects (then each file is stamped alone, as numba does)."""
    from numba.core import caching

    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if not isinstance(classes, list) or not all(
            hasattr(caching, n) for n in ("InTreeCacheLocator", "UserProvidedCacheLocator")):
        return False  # pragma: no cover - a numba without these internals

    class _PackageStamp:
        def get_source_stamp(self):
            return package_stamp()

        @classmethod
        def from_function(cls, py_func, py_file):
            if os.path.dirname(os.path.abspath(py_file)) not in PACKAGE_DIRS:
                return None
            return super().from_function(py_func, py_file)

    class PackageUserProvidedCacheLocator(_PackageStamp, caching.UserProvidedCacheLocator):
        """NUMBA_CACHE_DIR, stamped with the whole of the stamped packages."""

    class PackageInTreeCacheLocator(_PackageStamp, caching.InTreeCacheLocator):
        """__pycache__ next to the source, stamped with the whole of the stamped packages."""

    if any(getattr(c, "__qualname__", "").startswith("_register_locators.") for c in classes):
        return True  # already registered (a reload of this module)
    classes[:0] = [PackageUserProvidedCacheLocator, PackageInTreeCacheLocator]
    return True


LOCATORS_REGISTERED = _register_locators()


def fresh_llvm_ir(dispatcher) -> dict:
    """The LLVM IR of every signature ``dispatcher`` has been compiled for, from a fresh,
    uncached compile of the same Python function with the same options.

    A function loaded from numba's disk cache keeps only machine code, so its IR cannot be
    inspected; compiling a whole process fresh (an empty ``NUMBA_CACHE_DIR``) recompiles every
    kernel it calls too, minutes for the contact kernels. Here only the inspected function is
    recompiled: the compiled functions it calls are the same dispatchers, from the cache, and
    appear in its IR by their (mangled) names; the functions it inlines are inlined again, as in
    the cached code. Tests use this to check which code a kernel holds (docs/inhouse.md,
    "Control and contacts in the step")."""
    import numba

    options = {k: v for k, v in dispatcher.targetoptions.items() if k != "cache"}
    fresh = numba.njit(**options)(dispatcher.py_func)
    out = {}
    for sig in dispatcher.signatures:
        fresh.compile(sig)
        out[sig] = fresh.inspect_llvm(sig)
    return out
