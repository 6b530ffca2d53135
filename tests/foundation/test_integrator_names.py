"""crosscheck.names is the one light-weight table of every engine's integrators (names, order,
scheme, symplecticity, contact) that the loader, the runner, the adapters, the in-house registry
and the conformance suite read. These tests fail when an adapter, the in-house rigid registry or
the fluid solver disagrees with it, so nothing can be added in one place and forgotten in
another."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest

from crosscheck import names
from crosscheck.engines import REGISTRY, get_engine
from crosscheck.names import FINE_STEP_ONLY, INTEGRATOR_NAMES, all_integrator_names
from crosscheck.scene.model import ENGINE_NAMES

REPO = Path(__file__).resolve().parents[2]


def test_every_engine_has_an_entry_and_nothing_else_does():
    assert set(INTEGRATOR_NAMES) == set(ENGINE_NAMES) == set(REGISTRY)


@pytest.mark.parametrize("engine", ENGINE_NAMES)
def test_the_list_is_the_adapters_own_in_its_order(engine):
    # Order matters: the first entry is the engine's default integrator.
    assert get_engine(engine).capabilities().integrators == INTEGRATOR_NAMES[engine]


def test_the_adapters_module_tuples_agree():
    from crosscheck.engines import mujoco, pybullet, pymunk

    # MuJoCo also runs mapped fluid cases as "integrator+model" (names.medium_run_names)
    assert mujoco.INTEGRATORS + names.medium_run_names("mujoco") == INTEGRATOR_NAMES["mujoco"]
    assert pybullet.INTEGRATORS == INTEGRATOR_NAMES["pybullet"]
    assert pymunk.INTEGRATORS == INTEGRATOR_NAMES["pymunk"]


def test_every_entry_is_well_formed():
    for engine, infos in names.RIGID.items():
        assert infos, engine
        for info in infos:
            assert info.scheme in names.SCHEMES, (engine, info)
            assert info.order >= 1 and isinstance(info.symplectic, bool), (engine, info)
            assert isinstance(info.contact, bool), (engine, info)
            # second order and above is exact under constant acceleration, first order is not
            assert (info.scheme == names.EXACT) == (info.order >= 2), (engine, info)
        assert not set(names.rigid_names(engine)) & set(names.fluid_names(engine))


def test_the_old_location_reexports_the_table():
    from crosscheck.engines import names as old

    assert old.INTEGRATOR_NAMES is INTEGRATOR_NAMES


def test_names_imports_nothing_heavy():
    code = ("import sys\nimport crosscheck.names\n"
            "print(sorted(m for m in sys.modules if m.startswith('crosscheck.') "
            "or m.split('.')[0] in ('numba', 'numpy', 'mujoco', 'pybullet', 'pymunk')))\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "['crosscheck.names']"


def test_inhouse_is_the_rigid_registry_then_the_contact_runs_then_the_fluid_schemes():
    # The in-house adapter lists the fluid schemes only when crosscheck.sim.fluid imports, so the
    # adapter test above alone would not catch a fluid scheme missing from the list.
    from crosscheck.sim import fluid, rigid

    rigid_names = tuple(rigid.INTEGRATORS)
    fluid_names = tuple(fluid.INTEGRATORS)
    assert rigid_names == names.rigid_names("inhouse")
    assert fluid_names == names.fluid_names("inhouse")
    assert INTEGRATOR_NAMES["inhouse"] == (rigid_names + names.contact_run_names("inhouse")
                                           + fluid_names)
    assert rigid_names[0] == rigid.DEFAULT


def test_fine_step_only_names_are_what_the_comparer_runs_without_an_engine():
    from crosscheck.reference.spec import reference_spec
    from crosscheck.scene.loader import load_case

    scene = load_case(REPO / "cases" / "rigid3d" / "free_fall.toml")
    for name in FINE_STEP_ONLY:
        ref = dataclasses.replace(scene.reference, kind="fine-step", integrator=name)
        spec = reference_spec(dataclasses.replace(scene, reference=ref), 1e-3)
        assert spec["kind"] == name  # run by SciPy, not by an engine's integrator
        assert name not in all_integrator_names()


def test_loading_every_case_imports_no_engine():
    # The reason the names live apart from the adapters: loading must stay fast and must not
    # break when an engine package is missing.
    code = ("import sys\n"
            "from crosscheck.scene.loader import find_cases, load_case\n"
            "for p in find_cases(['cases']):\n"
            "    load_case(p)\n"
            "heavy = ('numba', 'mujoco', 'pybullet', 'pymunk')\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy\n"
            "             or m.startswith(('crosscheck.sim', 'crosscheck.engines.inhouse',\n"
            "                              'crosscheck.engines.mujoco',\n"
            "                              'crosscheck.engines.pybullet',\n"
            "                              'crosscheck.engines.pymunk'))))\n")
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[]"


# -- the pytest plugin ----------------------------------------------------------------------------
CASE = """[case]
name = "typo"
dimension = 3
[run]
duration = 0.1
dt = 0.01
engines = ["inhouse", "mujoco"]
integrators = {{ mujoco = [{name}] }}
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 1.0
position = [0.0, 0.0, 0.0]
"""


def _pytest(root: Path, *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", *args],
                          cwd=root, env=env, capture_output=True, text=True, timeout=300)


def test_pytest_plugin_refuses_a_misspelt_integrator_at_collection(tmp_path):
    (tmp_path / "cases").mkdir()
    (tmp_path / "cases" / "typo.toml").write_text(CASE.format(name='"rk5"'))
    res = _pytest(tmp_path, "cases/")
    assert res.returncode == 2, res.stdout + res.stderr
    assert "run.integrators.mujoco[0]: expected an integrator of mujoco, one of ['euler'" \
        in res.stdout
    assert "Traceback" not in res.stdout and "not applicable" not in res.stdout


@pytest.mark.slow
def test_pytest_plugin_refuses_an_unknown_integrator_option(tmp_path):
    (tmp_path / "cases").mkdir()
    (tmp_path / "cases" / "ok.toml").write_text(CASE.format(name='"rk4"'))
    res = _pytest(tmp_path, "cases/", "--crosscheck-integrators", "mujoco.rk5",
                  "--collect-only")
    assert res.returncode == 2, res.stdout + res.stderr
    assert "--crosscheck-integrators: mujoco has no integrator 'rk5'" in res.stdout
    # The same case with a valid name collects one item per listed integrator.
    res = _pytest(tmp_path, "cases/", "--crosscheck-integrators", "mujoco.rk4",
                  "--collect-only", "-q")
    assert res.returncode == 0, res.stdout + res.stderr
    assert "cases/ok.toml::mujoco-rk4" in res.stdout


def test_the_contact_flags_agree_with_what_each_adapter_can_simulate():
    # names.py says which integrators run with contact; each adapter's capabilities say
    # whether it maps contact at all. They must agree, else the registry lies to the runner.
    from crosscheck.engines import get_engine
    from crosscheck.names import RIGID
    from crosscheck.sim.rigid.contact_models import CONTACT_KERNELS

    for engine, infos in RIGID.items():
        maps_contact = "contact" in get_engine(engine).capabilities().effects
        if engine in names.CONTACT_MODELS:
            # The in-house engine maps contact once a model is implemented; an integrator's flag
            # says it pairs with some model.
            assert maps_contact == bool(CONTACT_KERNELS)
            paired = {i for m in names.CONTACT_MODELS[engine] for i in m.integrators}
            assert all(info.contact == (info.name in paired) for info in infos), engine
        else:
            assert all(info.contact == maps_contact for info in infos), (engine, maps_contact)


def test_contact_run_names_resolve_to_integrator_and_model():
    assert names.split_run("rk4+penalty") == ("rk4", "penalty")
    assert names.split_run("rk4") == ("rk4", None)
    # A bare in-house integrator on a contact scene carries its first pairing model, so a report
    # always names both; contact-free scenes and the peers keep the bare name.
    assert names.resolve_run("inhouse", "rk4", contact=True) == "rk4+penalty"
    assert names.resolve_run("inhouse", "symplectic_euler", contact=True) == \
        "symplectic_euler+soft_step"
    assert names.resolve_run("inhouse", "rk4", contact=False) == "rk4"
    assert names.resolve_run("mujoco", "euler", contact=True) == "euler"
    assert names.resolve_run("inhouse", "implicit_euler", contact=True) == "implicit_euler"
    for run in names.contact_run_names("inhouse"):
        integrator, model = names.split_run(run)
        assert integrator in names.contact_model_info("inhouse", model).integrators
        assert names.integrator_info("inhouse", integrator).contact
