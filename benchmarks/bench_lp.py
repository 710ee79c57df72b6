"""LP thruster allocation (core.lp_allocation, issue 13): time per solve.

Usage::

    .venv/bin/python benchmarks/bench_lp.py [--solves N] [--batches K]

Two geometries: ``configs/vehicles/generic-12.yaml`` (12 thrusters in couples) and a random
12-thruster geometry (positions uniform in a 2 m cube, random directions and limits). For each,
N attainable torques (random thrusts, about half the thrusters firing) are solved inside one
jitted loop (no Python dispatch per solve, as in the flight kernel), K times; the median batch
over N gives the time per solve. Also timed: the same solves through the Python wrapper, and
scipy's linprog (HiGHS) on a tenth of them, for scale. Target: <= 5 us per solve.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from scipy.optimize import linprog  # noqa: E402

from refexmc._jit import jit  # noqa: E402
from refexmc.config import derived  # noqa: E402
from refexmc.config.load import load_vehicle  # noqa: E402
from refexmc.core import lp_allocation as lp  # noqa: E402

TARGET_US = 5.0


@jit
def solve_all(arms, u_max, torques, out, work, basis, in_basis):
    total = 0.0
    for k in range(torques.shape[0]):
        total += lp.allocate(arms, u_max, torques[k], out[k], work, basis, in_basis)
    return total


def geometries():
    vehicle = load_vehicle(ROOT / "configs/vehicles/generic-12.yaml")
    rng = np.random.default_rng(7)
    positions = rng.uniform(-1.0, 1.0, (12, 3))
    directions = rng.normal(size=(12, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    return {
        "generic-12": (np.ascontiguousarray(derived.torque_arms(vehicle).T), np.full(12, 1.0)),
        "random-12": (np.ascontiguousarray(np.cross(positions, directions).T), rng.uniform(0.5, 2.0, 12)),
    }


def bench(arms, u_max, solves, batches):
    rng = np.random.default_rng(1)
    n = arms.shape[1]
    thrusts = rng.uniform(0.0, 1.0, (solves, n)) * (rng.random((solves, n)) < 0.5) * u_max
    torques = np.ascontiguousarray(thrusts @ arms.T)
    out = np.zeros((solves, n))
    work = np.zeros(lp.scratch_shape(n))
    basis = np.zeros(3, dtype=np.int64)
    in_basis = np.zeros(lp.work_columns(n), dtype=np.bool_)
    solve_all(arms, u_max, torques[:10], out[:10], work, basis, in_basis)  # compile or load
    times = []
    for _ in range(batches):
        t0 = time.perf_counter()
        solve_all(arms, u_max, torques, out, work, basis, in_basis)
        times.append((time.perf_counter() - t0) / solves * 1e6)
    residual = np.abs(np.einsum("ij,kj->ki", arms, out) - torques).max()
    t0 = time.perf_counter()
    u = np.zeros(n)
    for torque in torques[: solves // 10]:
        lp.allocate(arms, u_max, torque, u, work, basis, in_basis)
    wrapper_us = (time.perf_counter() - t0) / (solves // 10) * 1e6
    count = max(1, solves // 100)
    t0 = time.perf_counter()
    for torque in torques[:count]:
        linprog(np.ones(n), A_eq=arms, b_eq=torque, bounds=[(0.0, float(t)) for t in u_max], method="highs")
    highs_us = (time.perf_counter() - t0) / count * 1e6
    return float(np.median(times)), float(min(times)), wrapper_us, highs_us, float(residual)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--solves", type=int, default=100_000)
    parser.add_argument("--batches", type=int, default=7)
    args = parser.parse_args()
    header = ("geometry", "median us", "min us", "wrapper us", "HiGHS us", "max |Hu-tau|")
    print("{:12s} {:>10s} {:>8s} {:>11s} {:>9s} {:>13s}  target".format(*header))
    for name, (arms, u_max) in geometries().items():
        median, fastest, wrapper, highs, residual = bench(arms, u_max, args.solves, args.batches)
        verdict = "PASS" if median <= TARGET_US else "FAIL"
        row = f"{name:12s} {median:10.3f} {fastest:8.3f} {wrapper:11.3f} {highs:9.0f} {residual:13.2e}"
        print(f"{row}  <= {TARGET_US:g} us {verdict}")


if __name__ == "__main__":
    main()
