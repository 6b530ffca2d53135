"""Run one task in a fresh Python process with a wall-time limit (``python -m`` this module).

Used where the caller cannot own long-lived workers: inside a Dask worker (which may not fork
multiprocessing children of its own and must survive an engine segfault or a hang). The task goes
in as a JSON file, the result comes back as a JSON file written atomically; the child's output
goes to a log whose tail explains a crash. On timeout the child's whole process group is killed.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from crosscheck.runner.cell import base_result


def _clean(value):
    """JSON-safe copy: non-finite floats become None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if hasattr(value, "tolist"):
        return _clean(value.tolist())
    return value


def run_isolated(task: dict[str, Any]) -> dict[str, Any]:
    """Execute ``task`` in a child interpreter; crash, hang and timeout become results."""
    from crosscheck.runner.local import describe_exit

    timeout = float(task.get("timeout") or 600.0)
    with tempfile.TemporaryDirectory(prefix="crosscheck-cell-") as tmp:
        tmp = Path(tmp)
        task_file, result_file, log_file = tmp / "task.json", tmp / "result.json", tmp / "log.txt"
        task_file.write_text(json.dumps(_clean(task)))
        env = dict(os.environ)
        paths = [p for p in task.get("sys_path") or [] if p]
        if env.get("PYTHONPATH"):
            paths.append(env["PYTHONPATH"])
        if paths:
            env["PYTHONPATH"] = os.pathsep.join(paths)
        with open(log_file, "wb") as log:
            proc = subprocess.Popen(
                [sys.executable, "-m", "crosscheck.runner.isolated", str(task_file),
                 str(result_file)],
                stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env,
                start_new_session=True)
            try:
                code = proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                _kill_group(proc)
                result = base_result(task)
                result.update(status="timeout",
                              reason=f"no result after {timeout:g} s wall time; process killed")
                return result
        if code == 0 and result_file.exists():
            return json.loads(result_file.read_text())
        tail = log_file.read_text(errors="replace")[-1500:].strip()
        result = base_result(task)
        result.update(status="error", reason=describe_exit(code) + (f"\n{tail}" if tail else ""))
        return result


def _kill_group(proc: subprocess.Popen) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        proc.kill()
    proc.wait()


def main(argv: list[str]) -> int:  # pragma: no cover - runs in the child process
    from crosscheck.runner.cell import execute_task

    task = json.loads(Path(argv[0]).read_text())
    result = execute_task(task)
    out = Path(argv[1])
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(_clean(result)))
    tmp.replace(out)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
