"""`crosscheck inertia`, driven through a small argparse harness (independent of cli.py)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from crosscheck.commands import inertia
from crosscheck.scene import massprops as mp

MESHES = Path(__file__).resolve().parents[1] / "cases" / "meshes"
L_BRACKET = MESHES / "l_bracket.obj"
NOT_CLOSED = MESHES / "not_closed.obj"


def run_cli(*argv) -> int:
    parser = argparse.ArgumentParser(prog="crosscheck")
    inertia.register(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["inertia", *map(str, argv)])
    return args.func(args)


def run_json(capsys, *argv) -> dict:
    assert run_cli(*argv, "--json") == 0
    out = capsys.readouterr().out
    return json.loads(out)


def test_json_output_matches_library(capsys):
    res = run_json(capsys, L_BRACKET, "--density", 2700, "--samples", 20000, "--seed", 3)
    assert res["density"] == 2700.0 and res["samples"] == 20000 and res["seed"] == 3
    mesh = mp.load_mesh(L_BRACKET)
    exact = mp.mesh_mass_properties(mesh.vertices, mesh.faces, 2700.0)
    sampled = mp.sampled_mass_properties(mesh, 2700.0, 20000, 3)
    ex, bb, sm = (res["methods"][k] for k in ("exact", "bounding_box", "sampling"))
    assert ex["mass"] == pytest.approx(exact.mass, rel=1e-15)
    np.testing.assert_allclose(ex["inertia"], exact.inertia, rtol=1e-15)
    np.testing.assert_allclose(ex["principal_moments"], exact.principal()[0], rtol=1e-15)
    np.testing.assert_allclose(sm["inertia"], sampled.inertia, rtol=1e-15)
    assert "error" not in ex
    for m in (ex, bb, sm):
        assert isinstance(m["com"], list) and len(m["inertia"]) == 3
        assert m["wall_time_s"] >= 0
    # errors as documented, recomputed here
    diag = np.linalg.norm(np.subtract(*mesh.bounds[::-1]))
    assert sm["error"]["mass_rel"] == pytest.approx(abs(sampled.mass / exact.mass - 1), rel=1e-9)
    assert sm["error"]["com_rel_diag"] == pytest.approx(
        np.linalg.norm(sampled.com - exact.com) / diag, rel=1e-9)
    assert sm["error"]["inertia_rel_fro"] == pytest.approx(
        np.linalg.norm(sampled.inertia - exact.inertia) / np.linalg.norm(exact.inertia), rel=1e-9)
    # the L bracket fills ~1/11 of its bounding box; sampling is far better than the box
    assert bb["error"]["mass_rel"] > 5
    assert sm["error"]["inertia_rel_fro"] < 0.1 < bb["error"]["inertia_rel_fro"]


def test_seed_reproducible(capsys):
    a = run_json(capsys, L_BRACKET, "--samples", 5000, "--seed", 1)["methods"]["sampling"]
    b = run_json(capsys, L_BRACKET, "--samples", 5000, "--seed", 1)["methods"]["sampling"]
    c = run_json(capsys, L_BRACKET, "--samples", 5000, "--seed", 2)["methods"]["sampling"]
    assert a["inertia"] == b["inertia"] and a["mass"] == b["mass"]
    assert a["inertia"] != c["inertia"]


def test_defaults():
    parser = argparse.ArgumentParser(prog="crosscheck")
    inertia.register(parser.add_subparsers())
    args = parser.parse_args(["inertia", "m.obj"])
    assert (args.density, args.samples, args.json) == (1000.0, 100_000, False)
    assert args.func is inertia.run


def test_table_output(capsys):
    assert run_cli(L_BRACKET, "--samples", 2000) == 0
    out = capsys.readouterr().out
    for text in ("divergence theorem (exact)", "bounding box", "point sampling",
                 "mass [kg]", "inertia [kg m^2]", "principal moments", "wall time [s]",
                 "inertia error (rel Frobenius)"):
        assert text in out


@pytest.mark.parametrize("make", ["missing", "open", "garbage"])
def test_bad_mesh_one_line_error(capsys, tmp_path, make):
    path = {"missing": tmp_path / "missing.obj", "open": NOT_CLOSED,
            "garbage": tmp_path / "garbage.obj"}[make]
    if make == "garbage":
        path.write_text("not a mesh at all\n")
    assert run_cli(path) == 2
    cap = capsys.readouterr()
    assert cap.out == ""
    lines = cap.err.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"error: {path}: ")
    assert "closed, consistently oriented triangle mesh (watertight)" in lines[0]
    assert "Traceback" not in cap.err


def test_bad_numbers_rejected(capsys):
    assert run_cli(L_BRACKET, "--samples", 0) == 2
    assert run_cli(L_BRACKET, "--density", -1) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and all(e.startswith("error: ") for e in err)
