"""``[reference] kind = "table"`` at load (issue 13 point 2): a table that cannot describe the
case is refused with its field path, so no cell can pass by measuring nothing.

* published tables: unknown names, a fluid table on a rigid case, a cavity at a Reynolds number
  Ghia et al. do not tabulate;
* the Ghia tables themselves, a few values checked against the paper (Tables I and II);
* the case's own CSV (``reference.file``): every bad file refused where it is named.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crosscheck.errors import CaseError
from crosscheck.reference.fluid_data import GHIA_REYNOLDS, TABLES, load_table
from crosscheck.scene.loader import load_case, load_case_text

CASES = Path(__file__).resolve().parents[2] / "cases"

RIGID = """
[case]
name = "fall"
dimension = 3
[run]
duration = 1.0
dt = 0.01
engines = ["inhouse"]
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.1 } }
mass = 2.0
position = [0, 0, 10]
[reference]
kind = "table"
"""

CAVITY = """
[case]
name = "cavity"
dimension = 2
[run]
duration = 1.0
dt = 0.01
engines = ["inhouse"]
[fluid]
domain = [{side}, {side}]
resolution = [16, 16]
density = 1.0
kinematic_viscosity = {nu}
lid = {{ side = "top", speed = {speed} }}
[reference]
kind = "table"
table = "{table}"
"""


def cavity(table="ghia_1982", nu=0.01, speed=1.0, side=1.0):
    return CAVITY.format(table=table, nu=nu, speed=speed, side=side)


def refused(text, field, *needles, base_dir="."):
    with pytest.raises(CaseError) as info:
        load_case_text(text, "c.toml", base_dir)
    err = info.value
    assert err.field == field, str(err)
    for needle in needles:
        assert needle in str(err), str(err)
    return err


# -- published tables ----------------------------------------------------------------------------
def test_unknown_table_is_refused_with_the_known_ones():
    err = refused(cavity(table="ghia_1928"), "reference.table", "ghia_1928", "ghia_1982",
                  "martin_moyce_1952")
    assert "ghia_1982_re400" in err.expected


def test_a_fluid_table_on_a_rigid_case_is_refused():
    refused(RIGID + 'table = "martin_moyce_1952"\n', "reference.table", "rigid")


def test_a_table_key_without_kind_table_is_refused():
    text = RIGID.replace('kind = "table"', 'kind = "none"') + 'table = "ghia_1982"\n'
    refused(text, "reference.table", 'reference.kind = "table"')


def test_dam_break_table_needs_a_free_surface():
    refused(cavity(table="martin_moyce_1952"), "reference.table", "free surface")


@pytest.mark.parametrize("re", GHIA_REYNOLDS)
def test_every_ghia_reynolds_number_loads(re):
    # Re = U L / nu with L = 2 m: the side counts, not only the viscosity
    scene = load_case_text(cavity(nu=2.0 / re, side=2.0))
    assert scene.reference.table == "ghia_1982"
    assert load_case_text(cavity(table=f"ghia_1982_re{re}", nu=2.0 / re, side=2.0))


def test_reynolds_150_is_refused_naming_what_exists():
    err = refused(cavity(nu=1.0 / 150), "reference.table", "150", "100, 400, 1000, 3200, 5000, "
                  "7500, 10000", "1e-06")
    assert "matches no table" in err.expected


def test_a_named_reynolds_number_must_be_the_cases():
    refused(cavity(table="ghia_1982_re400", nu=0.01), "reference.table", "= 100",
            "Re = 400")


def test_reynolds_number_matches_to_round_off_only():
    load_case_text(cavity(nu=1 / 1000 * (1 + 1e-9)))  # 1000 to round-off
    refused(cavity(nu=1 / 1000 * (1 + 1e-4)), "reference.table", "matches no table")


def test_cavity_table_needs_a_square_top_lid_cavity():
    refused(cavity(speed=-1.0, nu=-0.01 * -1), "reference.table", "+x")
    refused(cavity().replace("domain = [1.0, 1.0]", "domain = [2.0, 1.0]")
            .replace("[16, 16]", "[32, 16]"), "reference.table", "square")
    two = cavity().replace('lid = { side = "top", speed = 1.0 }',
                           'lid = [{ side = "top", speed = 1.0 }, { side = "left", speed = 1.0 }]')
    assert "side = \"left\"" in two
    refused(two, "reference.table", "2 moving sides")


def test_the_shipped_cavity_case_loads_at_re_100():
    scene = load_case(CASES / "fluid" / "lid_driven_cavity.toml")
    assert scene.reference.table == "ghia_1982_re100"


def test_ghia_tables_as_transcribed_from_the_paper():
    """A few entries of Ghia, Ghia & Shin (1982), Table I (u at x = 0.5) and Table II (v at
    y = 0.5), one per column, read off the paper's layout (17 rows, y and x descending)."""
    checks = {  # (table, Re, position) -> value
        ("u", 400, 0.2813): -0.32726, ("u", 400, 0.9766): 0.75837,
        ("u", 1000, 0.1719): -0.38289, ("u", 1000, 0.5000): -0.06080,
        ("u", 3200, 0.1016): -0.41933, ("u", 5000, 0.0703): -0.43643,
        ("u", 7500, 0.7344): 0.20591, ("u", 10000, 0.9609): 0.48070,
        ("v", 400, 0.8594): -0.44993, ("v", 400, 0.5000): 0.05186,
        ("v", 1000, 0.9063): -0.51550, ("v", 1000, 0.5000): 0.02526,
        ("v", 3200, 0.0938): 0.42768, ("v", 5000, 0.9531): -0.55408,
        ("v", 7500, 0.0703): 0.44030, ("v", 10000, 0.9688): -0.54302,
    }
    for (comp, re, pos), value in checks.items():
        t = load_table(f"ghia_1982_re{re}_{comp}")
        coord = t["y"] if comp == "u" else t["x"]
        i = int(np.flatnonzero(np.isclose(coord, pos))[0])
        assert t[comp][i] == value, (comp, re, pos)
    for re in GHIA_REYNOLDS:
        u, v = load_table(f"ghia_1982_re{re}_u"), load_table(f"ghia_1982_re{re}_v")
        assert any(f"Table I, column Re = {re}" in line for line in u.source)
        assert any(f"Table II, column Re = {re}" in line for line in v.source)
        # 17 rows each, less the two misprints left out (documented in the files)
        assert len(u["y"]) == (16 if re in (3200, 10000) else 17) and len(v["x"]) == 17
        assert u["u"][0] == 1.0 and u["u"][-1] == 0.0 and v["v"][0] == v["v"][-1] == 0.0
    # exactly one u and one v table per Reynolds number of the paper, none other
    assert sorted(k for k in TABLES if k.startswith("ghia_1982")) == sorted(
        f"ghia_1982_re{re}_{c}" for re in GHIA_REYNOLDS for c in "uv")


# -- the case's own table --------------------------------------------------------------------------
def write(tmp_path, body, name="data.csv"):
    (tmp_path / name).write_text(body)
    return RIGID + f'file = "{name}"\n'


GOOD = "# my measurements\nt,com_z,vel_z\n0.0,10.0,0.0\n0.5,8.77375,-4.905\n1.0,5.095,-9.81\n"


def test_a_rigid_series_loads(tmp_path):
    scene = load_case_text(write(tmp_path, GOOD), "c.toml", tmp_path)
    data = scene.reference.data
    assert data.axis == "t" and data.compared == ("com_z", "vel_z") and data.body == 0
    assert data.source == ("my measurements",)
    np.testing.assert_array_equal(data.columns["t"], [0.0, 0.5, 1.0])


@pytest.mark.parametrize("body, expected", [
    ("t,com_z\n0,1\n0.5\n", "2 comma-separated values on every row"),
    ("t,com_z\n0,abc\n", "a number in column 'com_z'"),
    ("t,com_z\n0,nan\n", "a finite number in column 'com_z'"),
    ("t,com_z\n0,inf\n", "a finite number"),
    ("t,height\n0,1\n", "column names this case can compare"),
    ("t,com_z\n0,1\n0.5,2\n0.5,3\n", "strictly increasing t"),
    ("t,com_z\n0.5,1\n0,2\n", "strictly increasing t"),
    ("t,com_z\n0,1\n2.0,3\n", "times within the run"),
    ("t,com_z,com_z\n0,1,1\n", "each column once"),
    ("# only a comment\n", "a header line and at least one row"),
    ("t,com_z\n", "a header line and at least one row"),
    ("x,u\n0,1\n", "a time series"),
    ("s,com_z\n0,1\n", "first column is t"),
])
def test_bad_csv_is_refused_at_reference_file(tmp_path, body, expected):
    refused(write(tmp_path, body), "reference.file", expected, "data.csv", base_dir=tmp_path)


def test_missing_and_unreadable_files_are_refused(tmp_path):
    refused(RIGID + 'file = "nope.csv"\n', "reference.file", "a readable CSV file", "nope.csv",
            base_dir=tmp_path)
    (tmp_path / "bin.csv").write_bytes(b"t,com_z\n\xff\xfe\n")
    refused(RIGID + 'file = "bin.csv"\n', "reference.file", "UTF-8", base_dir=tmp_path)


def test_table_and_file_together_are_refused(tmp_path):
    text = write(tmp_path, GOOD) + 'table = "ghia_1982"\n'
    refused(text, "reference.file", "only one of table")


def test_several_bodies_need_reference_body(tmp_path):
    two = write(tmp_path, GOOD).replace("[reference]", """[[bodies]]
name = "other"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [1, 0, 10]
[reference]""")
    refused(two, "reference.body", "required", base_dir=tmp_path)
    scene = load_case_text(two + 'body = "other"\n', "c.toml", tmp_path)
    assert scene.reference.data.body == 1
    refused(two + 'body = "nobody"\n', "reference.body", "the name of a body",
            base_dir=tmp_path)


def test_fluid_profile_is_checked_against_the_domain(tmp_path):
    base = cavity().replace('table = "ghia_1982"', 'file = "p.csv"')
    (tmp_path / "p.csv").write_text("y,u\n0.25,-0.1\n0.75,0.2\n")
    refused(base, "reference.x", "required", base_dir=tmp_path)
    scene = load_case_text(base + "x = 0.5\n", "c.toml", tmp_path)
    assert scene.reference.data.axis == "y" and scene.reference.data.line == 0.5
    refused(base + "x = 1.5\n", "reference.x", "inside the domain", base_dir=tmp_path)
    (tmp_path / "p.csv").write_text("y,u\n0.25,-0.1\n1.75,0.2\n")
    refused(base + "x = 0.5\n", "reference.file", "within the domain", base_dir=tmp_path)
    (tmp_path / "p.csv").write_text("y,w\n0.25,-0.1\n")
    refused(base + "x = 0.5\n", "reference.file", "['u', 'v']", base_dir=tmp_path)
    # a fluid series: only quantities the run records (no front without a free surface)
    (tmp_path / "p.csv").write_text("t,front\n0.25,0.1\n")
    refused(base, "reference.file", "'kinetic_energy'", base_dir=tmp_path)
