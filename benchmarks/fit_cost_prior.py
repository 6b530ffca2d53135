"""The cost spread's prior (engines/driver.py CostPlan.prior_sd, prior_dof, run_sd), fitted on
fresh runs' cost passes (docs/metrics.md "Cost").

For every cell timed in k >= 2 passes, the sample variance s^2 of the log of its passes' figures
(each pass's minimum; and each pass's median) is, under the spread's model, sigma^2 times a
chi-square over k - 1, with sigma^2 itself drawn from the prior (a scaled inverse chi-square:
prior_sd^2, prior_dof degrees of freedom); so s^2 / prior_sd^2 follows an F(k - 1, prior_dof)
distribution, whose likelihood over all cells and runs is maximised here. The run offset
(run_sd) is read from the shift of all cells between two runs: the median over cells of the
log ratio of their figures, for every pair of runs (its standard deviation is sqrt(2) run_sd).

    python benchmarks/fit_cost_prior.py RUN_DIR [RUN_DIR ...] [--out FILE]

RUN_DIR holds a ``crosscheck run``'s results.json (benchmarks/bench_cost_stability.py --keep).
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import statistics
import sys
from pathlib import Path


def passes_of(doc: dict) -> dict[str, dict]:
    """Cell id -> its passes' minima, medians and processes (cells timed in 2+ passes)."""
    out = {}
    for c in doc.get("cells", []):
        d = c.get("cost_detail") or {}
        if len(d.get("process_minima") or []) >= 2:
            out[c["id"]] = {"minima": d["process_minima"], "medians": d["process_medians"],
                            "pids": d.get("process_pids")}
    return out


def fit_prior(runs: list[dict[str, dict]], key: str) -> tuple[float, float, int]:
    """(prior_sd, prior_dof, cells) maximising the F likelihood of the passes' variances."""
    import numpy as np
    from scipy.optimize import minimize
    from scipy.stats import f as fisher

    s2, dfs = [], []
    for run in runs:
        for cell in run.values():
            x = [math.log(v) for v in cell[key]]
            s2.append(statistics.variance(x))
            dfs.append(len(x) - 1)
    s2, dfs = np.array(s2), np.array(dfs)

    def nll(p):
        var, dof = math.exp(2 * p[0]), math.exp(p[1])
        return -float(np.sum(fisher.logpdf(s2 / var, dfs, dof) - math.log(var)))

    best = min((minimize(nll, [math.log(sd), math.log(dof)], method="Nelder-Mead")
                for sd in (0.01, 0.03) for dof in (1.0, 4.0)), key=lambda r: r.fun)
    return math.exp(best.x[0]), math.exp(best.x[1]), len(s2)


def run_shifts(runs: list[dict[str, dict]]) -> list[float]:
    """For every pair of runs, the median over cells of the log ratio of their minima's
    geometric means: the whole run's offset against the other."""
    out = []
    for a, b in itertools.combinations(runs, 2):
        both = [c for c in a if c in b]
        logs = [statistics.fmean(math.log(v) for v in a[c]["minima"])
                - statistics.fmean(math.log(v) for v in b[c]["minima"]) for c in both]
        if logs:
            out.append(statistics.median(logs))
    return out


def fit_report(runs: list[dict[str, dict]], title: str) -> list[str]:
    lines = [f"{title}: {len(runs)} runs, {sum(map(len, runs))} cell-runs "
             "(benchmarks/fit_cost_prior.py).", ""]
    for key in ("minima", "medians"):
        sd, dof, n = fit_prior(runs, key)
        lines.append(f"- passes' {key}: prior_sd {sd:.4f}, prior_dof {dof:.2f} ({n} cells)")
    shifts = run_shifts(runs)
    if shifts:
        lines.append("- whole-run shifts between pairs of runs (median over cells, log): "
                     + ", ".join(f"{s:+.3f}" for s in shifts))
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("runs", nargs="+")
    ap.add_argument("--title", default="Prior fitted")
    args = ap.parse_args(argv)
    runs = [passes_of(json.loads((Path(r) / "results.json").read_text())) for r in args.runs]
    print("\n".join(fit_report(runs, args.title)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
