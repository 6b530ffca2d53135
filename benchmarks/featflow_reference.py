"""The DFG 2D-2 reference values (src/crosscheck/reference/data/schafer_turek1996_cylinder.csv)
from FEATFLOW's published force series, measured the way crosscheck measures its own runs.

    python benchmarks/featflow_reference.py PATH/bdforces_q2_lv6_dt4

The file is FEATFLOW's reference computation of the benchmark (Q2 elements on mesh level 6,
Crank-Nicolson, dt = 1/1600), one line a step: index, time, boundary component, c_D, c_L. A
public copy: redbKIT/redbKIT, Problems/FEM_CFD_Dfg2D/ReferenceValues_Re100Periodic/ (commit
5081083a). It is not shipped here; this script lets anyone re-derive the numbers the reference
table quotes: the drag and lift extrema refined between samples by
:func:`crosscheck.compare.fluid_metrics.peak` and the Strouhal number from the lift's upward
zero crossings by :func:`crosscheck.compare.fluid_metrics.strouhal` (D = 0.1 m, U_mean = 1 m/s),
as :func:`crosscheck.compare.fluid_metrics.dfg_metrics` reads a run."""

import argparse
from pathlib import Path

import numpy as np

from crosscheck.compare.fluid_metrics import peak, strouhal

D, U_MEAN = 0.1, 1.0


def featflow_values(path: Path) -> dict[str, float]:
    """c_D,max, c_L,max, c_L,min, the mean lift and St of a FEATFLOW ``bdforces`` file."""
    try:
        data = np.loadtxt(path)
    except ValueError as exc:
        raise SystemExit(f"{path}: not a FEATFLOW bdforces file (index, time, component, c_D, "
                         f"c_L on each line): {exc}") from exc
    if data.ndim != 2 or data.shape[1] < 5:
        raise SystemExit(f"{path}: expected columns index, time, component, c_D, c_L")
    t, cd, cl = data[:, 1], data[:, 3], data[:, 4]
    st, periods = strouhal(t, cl, D, U_MEAN)
    # the mean lift over the whole periods between the first and the last upward crossing
    x = cl - cl.mean()
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    mean = float(np.mean(cl[up[0]:up[-1]])) if up.shape[0] > 1 else float("nan")
    return {"drag_coefficient_max": peak(cd), "lift_coefficient_max": peak(cl),
            "lift_coefficient_min": -peak(-cl), "lift_coefficient_mean": mean,
            "strouhal_number": st, "periods": float(periods), "t0": float(t[0]),
            "t1": float(t[-1])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("path", type=Path, help="a FEATFLOW bdforces file (2D-2)")
    args = ap.parse_args()
    if not args.path.is_file():
        raise SystemExit(f"{args.path}: no such file")
    for k, v in featflow_values(args.path).items():
        print(f"{k:24s} {v:.6g}")


if __name__ == "__main__":
    main()
