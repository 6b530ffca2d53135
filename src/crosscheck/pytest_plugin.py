"""pytest plugin: ``pytest cases/`` collects case files as tests (registered as ``pytest11``).

* A ``*.toml`` file is collected only when it has a top-level ``[case]`` table **and** lies under a
  path given on the pytest command line: a bare ``pytest`` (which uses ``testpaths``) collects no
  case files, and ``pyproject.toml`` or any other TOML is never taken for a case.
* One item per engine x integrator the case lists (each engine's default integrator when the case
  names none), with ids like ``cases/rigid3d/tennis_racket.toml::mujoco-rk4``.
* An item runs its cell exactly as ``crosscheck run`` does (same metrics and verdict), in the
  pytest process by default or, with ``--crosscheck-isolate``, in a child process killed at the
  case's ``run.timeout``. Pass: the item passes. Not applicable: skipped with the reason. Fail,
  blow-up, error, timeout: the item fails and shows the metric table. Metric values are recorded
  as ``user_properties`` (they appear in pytest's own ``--junitxml``).
* Shared references (fine-step, another engine) are computed once per test session and shared by
  the items and by pytest-xdist workers (``-n 2``) through files in pytest's cache folder, guarded
  by a lock file so two workers never compute the same one twice.
* A broken case file is a collection error whose message names the file and field.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
import uuid
from pathlib import Path

import pytest

from crosscheck.errors import CrosscheckError


def pytest_addoption(parser):
    group = parser.getgroup("crosscheck", "crosscheck case files")
    group.addoption("--crosscheck-engines", metavar="A,B", default=None,
                    help="only these engines (of those each case lists)")
    group.addoption("--crosscheck-integrators", metavar="X,Y", default=None,
                    help="these integrators instead of each case's ('engine.integrator' for one "
                         "engine)")
    group.addoption("--crosscheck-isolate", action="store_true",
                    help="run each case item in a child process with the case's timeout")
    group.addoption("--crosscheck-engine-ref", action="append", default=[],
                    metavar="NAME=MODULE:CLASS",
                    help="use this adapter class for engine NAME (adapters under development)")


def _requested_roots(config) -> list[Path]:
    if config.args_source != pytest.Config.ArgsSource.ARGS:
        return []
    base = Path(config.invocation_params.dir)
    roots = []
    for arg in config.args:
        path = Path(str(arg).split("::", 1)[0])
        roots.append((base / path).resolve())
    return roots


def _under(path: Path, roots: list[Path]) -> bool:
    path = path.resolve()
    return any(path == r or r in path.parents for r in roots)


def pytest_collect_file(file_path: Path, parent):
    if file_path.suffix != ".toml":
        return None
    if not _under(file_path, _requested_roots(parent.config)):
        return None
    from crosscheck.scene.loader import is_case_file

    if not is_case_file(file_path):
        return None
    return CaseFile.from_parent(parent, path=file_path)


def _engine_refs(config) -> dict[str, str]:
    out = {}
    for item in config.getoption("--crosscheck-engine-ref") or []:
        name, _, ref = item.partition("=")
        out[name.strip()] = ref.strip()
    return out


def _split(text):
    return [s.strip() for s in text.split(",") if s.strip()] if text else None


def _reference_dir(config) -> Path:
    """A folder shared by this session's xdist workers (the controller's run id names it)."""
    run_id = getattr(config, "workerinput", {}).get("testrunuid")
    if run_id is None:
        run_id = getattr(config, "_crosscheck_run_id", None) or uuid.uuid4().hex
        config._crosscheck_run_id = run_id
    cache = getattr(config, "cache", None)
    root = Path(cache.mkdir("crosscheck-references")) if cache is not None else Path(
        os.environ.get("TMPDIR", "/tmp")) / "crosscheck-references"
    root.mkdir(parents=True, exist_ok=True)
    _prune(root)
    folder = root / run_id
    folder.mkdir(exist_ok=True)
    return folder


def _prune(root: Path, max_age: float = 86400.0) -> None:
    now = time.time()
    for child in root.iterdir():
        try:
            if child.is_dir() and now - child.stat().st_mtime > max_age:
                shutil.rmtree(child, ignore_errors=True)
        except OSError:
            pass


class CaseFile(pytest.File):
    def collect(self):
        from crosscheck.runner.plan import build_matrix, check_integrators
        from crosscheck.scene.loader import load_case

        config = self.config
        refs = _engine_refs(config)
        # A misspelt integrator in the case is a collection error here, like any broken field.
        scene = load_case(self.path, unchecked_engines=refs)
        integrators = _split(config.getoption("--crosscheck-integrators"))
        check_integrators(integrators, refs, option="--crosscheck-integrators")
        matrix = build_matrix([scene], engines=_split(config.getoption("--crosscheck-engines")),
                              integrators=integrators, engine_refs=refs,
                              reference_dir=_reference_dir(config),
                              # pytest items are verdicts; cost is `crosscheck run`'s report
                              cost=False)
        references = {t["id"]: t for t in matrix.references}
        multi_dt = len({t["dt"] for t in matrix.cells}) > 1
        for task in matrix.cells:
            name = f"{task['engine']}-{task['integrator']}"
            if multi_dt:
                name += f"-dt{task['dt']:g}"
            yield CaseItem.from_parent(self, name=name, task=task,
                                       reference=references.get(task.get("depends_on")))

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, CrosscheckError):
            return str(excinfo.value)
        return super().repr_failure(excinfo)


class CellFailed(Exception):
    def __init__(self, result):
        self.result = result
        super().__init__(result.get("reason", ""))


class CaseItem(pytest.Item):
    def __init__(self, *, task, reference=None, **kwargs):
        super().__init__(**kwargs)
        self.task = task
        self.reference = reference

    def _execute(self, task):
        if self.config.getoption("--crosscheck-isolate"):
            from crosscheck.runner.isolated import run_isolated

            return run_isolated(dict(task, sys_path=[p for p in sys.path if p]))
        from crosscheck.runner.cell import execute_task

        return execute_task(task)

    def _ensure_reference(self, task):
        ref = self.reference
        path = Path(ref["path"])
        lock = path.with_name(path.name + ".lock")
        deadline = time.monotonic() + float(ref.get("timeout") or 600.0)
        while not path.exists():
            try:
                fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            except FileExistsError:
                if time.monotonic() > deadline:
                    task["reference_error"] = "timed out waiting for the shared reference run"
                    return
                time.sleep(0.2)
                continue
            os.close(fd)
            try:
                result = self._execute(ref)
            finally:
                lock.unlink(missing_ok=True)
            if result.get("status") != "ok":
                first = (result.get("reason") or "").splitlines()[:1]
                task["reference_error"] = f"reference run {result.get('status')}: " + (
                    first[0] if first else "")
                return
        task["reference_file"] = str(path)

    def runtest(self):
        task = dict(self.task)
        if self.reference is not None:
            self._ensure_reference(task)
        result = self._execute(task)
        for name, m in sorted((result.get("metrics") or {}).items()):
            self.user_properties.append((f"metric.{name}", m.get("value")))
            if m.get("limit") is not None:
                self.user_properties.append((f"limit.{name}", m["limit"]))
        if result.get("cost") is not None:
            self.user_properties.append(("cost", result["cost"]))
        status = result.get("status")
        if status == "not_applicable":
            # Reported at the case file, not at this line (pytest's item-location skip).
            raise pytest.skip.Exception(f"not applicable: {result.get('reason', '')}",
                                        _use_item_location=True)
        if status != "pass":
            raise CellFailed(result)

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, CellFailed):
            from crosscheck.compare.verdict import metric_table

            r = excinfo.value.result
            text = f"{r.get('status')}: {r.get('reason', '')}".rstrip()
            if r.get("metrics"):
                text += "\n\n" + metric_table(r["metrics"])
            return text
        return super().repr_failure(excinfo)

    def reportinfo(self):
        return self.path, 0, f"{self.task['case']} {self.name}"
