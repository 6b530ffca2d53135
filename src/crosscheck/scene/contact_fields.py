"""Reading the contact sections of a case: ``[materials]``, a ``material`` reference (a name or an
inline table), ``[[contact_pairs]]``, and the checks that tie them to ``[effects] contact``.

The pair rule that turns two materials into the values engines use is in
:mod:`crosscheck.scene.contact`; this module only reads and refuses (docs/cases.md, "Contact").
"""

from __future__ import annotations

from crosscheck.errors import CaseError
from crosscheck.scene.contact import GROUND, VALUES
from crosscheck.scene.fields import Fields
from crosscheck.scene.model import Material, PairOverride

DEFAULT_MATERIAL = Material(name="default")
MATERIAL_KEYS = ", ".join(VALUES)


def _values(f: Fields, dimension: int, defaults: dict[str, float | None]) -> dict:
    """The four contact values of a material or a pair entry, each checked with its unit."""
    if dimension == 2 and f.has("torsional_friction"):
        # Spin about an in-plane contact normal is a rotation out of the plane.
        raise f.error("torsional_friction", "no torsional_friction in a 2D case (spin about the "
                      "contact normal would leave the plane)", f.raw("torsional_friction"))
    out = {
        "friction": f.number("friction", defaults["friction"], nonnegative=True),
        "restitution": f.number("restitution", defaults["restitution"], nonnegative=True),
        "rolling_friction": f.number("rolling_friction", defaults["rolling_friction"],
                                     nonnegative=True, unit="m"),
        "torsional_friction": f.number("torsional_friction", defaults["torsional_friction"],
                                       nonnegative=True, unit="m"),
    }
    if out["restitution"] is not None and out["restitution"] > 1:
        raise f.error("restitution", "a coefficient between 0 and 1", out["restitution"])
    return out


def _material(f: Fields, name: str, dimension: int) -> Material:
    defaults = {k: getattr(DEFAULT_MATERIAL, k) for k in VALUES}
    material = Material(name=name, **_values(f, dimension, defaults))
    f.done()
    return material


def parse_materials(f: Fields, dimension: int) -> dict[str, Material]:
    """``[materials.<name>]``: free names; ``default`` always exists and may be redefined."""
    out = {"default": DEFAULT_MATERIAL}
    for key in list(f.table):
        out[key] = _material(f.sub(key), key, dimension)
    f.done()
    return out


def material_ref(f: Fields, materials: dict[str, Material], dimension: int) -> Material:
    """The ``material`` key of a body, a static or the ground: the name of a ``[materials]``
    entry, or an inline table with the same keys for a material used once (named by its field
    path, e.g. ``statics[0].material``, in show)."""
    value = f.raw("material", "default")
    if isinstance(value, dict):
        return _material(f.sub("material"), f.field("material"), dimension)
    if not isinstance(value, str):
        raise f.error("material", "a material name or an inline table { friction = ..., "
                      "restitution = ... }", value)
    if value not in materials:
        raise f.error("material", f"a material defined under [materials] ({sorted(materials)})",
                      value)
    return materials[value]


def parse_pair_overrides(entries: list[Fields], bodies: list[str], statics: list[str],
                         has_ground: bool, dimension: int) -> tuple[PairOverride, ...]:
    """``[[contact_pairs]]``: explicit values, or ``collide = false``, for one unordered pair."""
    names = bodies + statics + ([GROUND] if has_ground else [])
    out: list[PairOverride] = []
    for i, e in enumerate(entries):
        a = _pair_name(e, "a", names, has_ground)
        b = _pair_name(e, "b", names, has_ground)
        if a == b:
            raise e.error("b", "a name other than a (a pair of two different things)", b)
        if a not in bodies and b not in bodies:
            raise e.error("b", "a pair with at least one body (fixed geometry never touches "
                          "fixed geometry)", b)
        for earlier in out:
            if {earlier.a, earlier.b} == {a, b}:
                raise CaseError(e.file, e.path, f"one entry per pair (contact_pairs"
                                f"[{earlier.index}] already names {a!r} and {b!r})", [a, b])
        values = _values(e, dimension, dict.fromkeys(VALUES))
        given = [k for k in VALUES if values[k] is not None]
        collide = e.boolean("collide", True)
        if not collide and given:
            raise e.error(given[0], "no contact values with collide = false (the pair never "
                          "touches)", values[given[0]])
        if collide and not given:
            raise CaseError(e.file, e.path, f"at least one of {MATERIAL_KEYS} or "
                            "collide = false (an entry that changes nothing)")
        e.done()
        out.append(PairOverride(index=i, a=a, b=b, collide=collide, **values))
    return tuple(out)


def _pair_name(e: Fields, key: str, names: list[str], has_ground: bool) -> str:
    name = e.string(key)
    if name not in names:
        note = " (this case has no [ground])" if name == GROUND and not has_ground else ""
        raise e.error(key, f"the name of a body, a static or 'ground' {names}{note}", name)
    return name


def check_contact_sections(top: Fields, contact: bool, has_fluid: bool) -> None:
    """Statics and pair entries only mean something to contact, or (statics) to a fluid, whose
    obstacles they then are: a case that declares them where nothing uses them would silently
    carry geometry and values."""
    for key, what in (("statics", "[[statics]]"), ("contact_pairs", "[[contact_pairs]]")):
        if key == "statics" and has_fluid:
            continue  # a fluid case's statics are obstacles in the fluid (docs/fluid.md)
        if top.has(key) and not contact:
            raise top.error(key, f"[effects] contact = true in a case with {what} (without "
                            "contact nothing touches them)")


def check_reserved_names(bodies: list[str], file, contact: bool) -> None:
    """In a contact case "ground" names the ground plane in pairs, so no body may take it."""
    if contact and GROUND in bodies:
        i = bodies.index(GROUND)
        raise CaseError(file, f"bodies[{i}].name", "a name other than 'ground' in a contact "
                        "case (it names the [ground] plane in [[contact_pairs]])", GROUND)
