"""numba options of the in-house kernels, and one cache stamp for all of their modules.

The kernels are split by job (math3d; forces3d / forces2d; explicit3d / explicit2d, the
Runge-Kutta family; splitting3d / splitting2d, the symplectic family; implicit) and call, and
inline, each other's functions across modules. numba's on-disk cache (``cache=True``) stamps a
function's cached machine code with the hash of *its own* source file only, so after an edit to
a helper in math3d.py the cached RK4 step of explicit3d.py, which carries its own copy of the
helper, would be loaded unchanged: stale code, silently. This module therefore registers cache
locators for the files of this package whose source stamp is the hash of *every* ``.py`` file
in it: an edit anywhere in the package recompiles every kernel of the package (once; about a
minute for everything tests/rigid uses), never a stale one. They mirror numba's own two first
locators (``NUMBA_CACHE_DIR`` when set, else ``__pycache__`` next to the source) and take only
files of this package; every other file keeps numba's default locators. Import this module
before any kernel is decorated (every kernel module imports JIT / INLINE from here).
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

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))


def package_sources() -> list[str]:
    """The files whose content the kernels' cache stamp covers: every .py file of the package."""
    return sorted(os.path.join(PACKAGE_DIR, f) for f in os.listdir(PACKAGE_DIR)
                  if f.endswith(".py"))


def package_stamp() -> bytes:
    """sha256 over the package's source files (names and contents); numba memoises each file's
    hash by (path, mtime, size), so this costs a stat per file once the hashes are known."""
    from numba.core.caching import _hash_source_file

    digest = hashlib.sha256()
    for path in package_sources():
        st = os.stat(path)
        digest.update(os.path.basename(path).encode())
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
            if os.path.dirname(os.path.abspath(py_file)) != PACKAGE_DIR:
                return None
            return super().from_function(py_func, py_file)

    class PackageUserProvidedCacheLocator(_PackageStamp, caching.UserProvidedCacheLocator):
        """NUMBA_CACHE_DIR, stamped with the whole package."""

    class PackageInTreeCacheLocator(_PackageStamp, caching.InTreeCacheLocator):
        """__pycache__ next to the source, stamped with the whole package."""

    if any(getattr(c, "__qualname__", "").startswith("_register_locators.") for c in classes):
        return True  # already registered (a reload of this module)
    classes[:0] = [PackageUserProvidedCacheLocator, PackageInTreeCacheLocator]
    return True


LOCATORS_REGISTERED = _register_locators()
