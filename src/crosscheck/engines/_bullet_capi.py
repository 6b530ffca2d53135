"""Bullet's C client API inside PyBullet's own shared library, for the compiled recording loop.

Why: PyBullet's Python functions each cost ~1 us, as much as one step of a one-body scene, and a
sample needs two of them (``getBasePositionAndOrientation``, ``getBaseVelocity``): recording at
every tenth step added 33-44 % to bare stepping (benchmarks/results/overhead.md). PyBullet's
module is a build of Bullet's ``PhysicsClientC_API`` (``b3InitStepSimulationCommand``,
``b3SubmitClientCommandAndWaitStatus``, ``b3RequestActualStateCommandInit``, ...), and it exports
those functions. ``engines/_native.py`` calls them from a compiled loop with no Python per step
or sample, and one state request per body and sample instead of two.

The one thing PyBullet does not expose is the client handle behind a ``physicsClientId``: the
module keeps them in a static array, ``sPhysicsClients1[MAX_PHYSICS_CLIENTS]``. Its address is
in the shared library's own symbol table (``.symtab``, read with pyelftools): load address of
the library (an exported function's runtime address minus its symbol value) plus the array's
symbol value. Everything that could make this wrong is checked before the handle is used:

* the load address must agree for every exported function the loop calls (a different file on
  disk than the one loaded would disagree);
* the array must be an object of pointer size times a whole number of clients;
* on a scratch client, the handle must count the bodies PyBullet's ``getNumBodies`` counts, 0
  then 1, and Bullet's answers to a step and a state request give the status types the loop
  then requires of every call;
* the adapter then reads one sample both ways and uses the loop only if the rows are equal bit
  for bit (PybulletModel._native).

Anything missing (a stripped build, no pyelftools, another layout) makes ``api()`` return the
reason instead, and the adapter records through PyBullet's Python functions as before.
"""

from __future__ import annotations

import ctypes
import functools
from dataclasses import dataclass

import numpy as np

try:
    import pybullet as _p
except Exception:  # pragma: no cover - the adapter reports pybullet missing
    _p = None

# The functions the compiled loop calls, in the order of _native.bullet_* ``fns``.
FUNCTIONS = ("b3InitStepSimulationCommand", "b3SubmitClientCommandAndWaitStatus",
             "b3RequestActualStateCommandInit", "b3RequestActualStateCommandComputeLinkVelocity",
             "b3RequestActualStateCommandComputeForwardKinematics", "b3GetStatusActualState",
             "b3GetJointState", "b3GetLinkState", "b3GetStatusType")
# Applying forces before a step (_native.bullet_evaluate_forces / _bullet_apply_forces).
FORCE_FUNCTIONS = ("b3ApplyExternalForceCommandInit", "b3ApplyExternalForce",
                   "b3ApplyExternalTorque", "b3JointControlCommandInit2",
                   "b3JointControlSetDesiredForceTorque")
_CLIENTS = "sPhysicsClients1"  # pybullet.c: static b3PhysicsClientHandle sPhysicsClients1[...]


@dataclass(frozen=True)
class BulletApi:
    """Addresses of the C functions (``fns``, ``force_fns``), where the client handles live, and
    the status types of a completed step and a completed state request (``kinds``)."""

    fns: np.ndarray
    force_fns: np.ndarray
    clients: int
    max_clients: int
    kinds: np.ndarray

    def handle(self, cid: int) -> int:
        """The b3PhysicsClientHandle behind PyBullet's physicsClientId ``cid`` (0 if none)."""
        if not 0 <= cid < self.max_clients:
            return 0
        return int(ctypes.c_void_p.from_address(self.clients + 8 * cid).value or 0)


# Elf64_Sym. pyelftools reads the headers; the table itself (16 000 entries in PyBullet 3.2.7)
# is searched with NumPy: iterating it through pyelftools' Symbol objects took 0.38 s, paid
# once by every worker process that runs PyBullet.
_ELF64_SYM = np.dtype([("st_name", "<u4"), ("st_info", "u1"), ("st_other", "u1"),
                       ("st_shndx", "<u2"), ("st_value", "<u8"), ("st_size", "<u8")])
_SYMBOL_TYPES = {0: "STT_NOTYPE", 1: "STT_OBJECT", 2: "STT_FUNC"}


def _symbols(path: str, names: set[str]) -> dict[str, tuple[int, int, str]]:
    """name -> (value, size, type) from the ELF file's full symbol table (64-bit little-endian
    builds; anything else has no entries here, and api() reports that)."""
    from elftools.elf.elffile import ELFFile

    with open(path, "rb") as fh:
        elf = ELFFile(fh)
        table = elf.get_section_by_name(".symtab")
        if table is None or elf.elfclass != 64 or not elf.little_endian:
            return {}
        symbols = np.frombuffer(table.data(), dtype=_ELF64_SYM)
        strings = elf.get_section(table["sh_link"]).data()
    found: dict[str, tuple[int, int, str]] = {}
    for name in names:
        # Every offset where the name ends a string (linkers share string tails, so a symbol's
        # name may start inside a longer string), then the symbols named from one of them.
        key, offsets, start = name.encode() + b"\0", [], 0
        while (at := strings.find(key, start)) >= 0:
            offsets.append(at)
            start = at + 1
        hits = symbols[np.isin(symbols["st_name"], offsets)]
        if len(hits):
            sym = hits[0]
            found[name] = (int(sym["st_value"]), int(sym["st_size"]),
                           _SYMBOL_TYPES.get(int(sym["st_info"]) & 0xF, "other"))
    return found


@functools.lru_cache(maxsize=1)
def api() -> BulletApi | str:
    """The located API, or why it cannot be used (then the adapter stays in Python)."""
    if _p is None:  # pragma: no cover
        return "pybullet is not installed"
    if ctypes.sizeof(ctypes.c_void_p) != 8:  # pragma: no cover - 64-bit builds only
        return "not a 64-bit build"
    path = _p.__file__
    try:
        lib = ctypes.CDLL(path)  # the already-loaded module: dlopen returns the same image
        addresses = {name: ctypes.cast(getattr(lib, name), ctypes.c_void_p).value
                     for name in FUNCTIONS + FORCE_FUNCTIONS + ("b3GetNumBodies",)}
    except (OSError, AttributeError) as exc:  # pragma: no cover - every build exports them
        return f"PyBullet's library does not export Bullet's C API ({exc})"
    try:
        symbols = _symbols(path, set(addresses) | {_CLIENTS})
    except ImportError:  # pragma: no cover - pyelftools is a dependency
        return "pyelftools is not installed"
    except Exception as exc:  # pragma: no cover - an unreadable file
        return f"cannot read PyBullet's symbol table ({type(exc).__name__}: {exc})"
    if _CLIENTS not in symbols:
        return f"PyBullet's library has no symbol table entry for {_CLIENTS} (stripped build?)"
    bases = {addresses[n] - symbols[n][0] for n in addresses if n in symbols}
    if len(bases) != 1 or len(symbols) != len(addresses) + 1:
        return "PyBullet's symbol table does not match the loaded library"
    value, size, kind = symbols[_CLIENTS]
    if kind != "STT_OBJECT" or size <= 0 or size % 8:
        return f"{_CLIENTS} is not an array of handles ({kind}, {size} bytes)"
    fns = np.array([addresses[n] for n in FUNCTIONS], dtype=np.intp)
    force_fns = np.array([addresses[n] for n in FORCE_FUNCTIONS], dtype=np.intp)
    located = BulletApi(fns, force_fns, bases.pop() + value, size // 8, np.zeros(2, np.int64))
    return _check_on_scratch_client(located, addresses["b3GetNumBodies"])


def _check_on_scratch_client(located: BulletApi, num_bodies_fn: int) -> BulletApi | str:
    """Prove the handle lookup on a throwaway client and learn Bullet's status types."""
    count = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(num_bodies_fn)
    status_type = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(int(located.fns[8]))
    submit = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)(
        int(located.fns[1]))
    step = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p)(int(located.fns[0]))
    request = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int)(
        int(located.fns[2]))
    cid = _p.connect(_p.DIRECT)
    try:
        handle = located.handle(cid)
        if not handle or count(handle) != _p.getNumBodies(physicsClientId=cid) or \
                count(handle) != 0:
            return f"the {_CLIENTS} entry does not behave as PyBullet's client"
        uid = _p.createMultiBody(1.0, physicsClientId=cid)
        if count(handle) != 1:
            return f"the {_CLIENTS} entry does not see PyBullet's bodies"
        step_kind = status_type(submit(handle, step(handle)))
        read_kind = status_type(submit(handle, request(handle, uid)))
        failed_kind = status_type(submit(handle, request(handle, uid + 1)))  # no such body
        if len({step_kind, read_kind, failed_kind}) != 3:
            return "Bullet's status types do not tell a completed step or read from a failure"
    finally:
        _p.disconnect(physicsClientId=cid)
    return BulletApi(located.fns, located.force_fns, located.clients, located.max_clients,
                     np.array([step_kind, read_kind], np.int64))
