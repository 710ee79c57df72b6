"""IRASSI (issue 14): one 22 h reaction-wheel flight on one core.

Flies ``configs/missions/irassi-small-angle.yaml`` and ``irassi-large-angle.yaml`` with
``configs/vehicles/irassi.yaml`` (79,200 control periods at 1 Hz, 4 wheels, SMC, friction
compensation, the L2 gravity gradient inside RK4) through ``refexmc.simulate.fly`` after
compilation, pinned to one CPU; median, min and IQR of ``--reps`` flights each. Target: median
<= 100 ms. The history is decimated to one row per 10 minutes, as the campaign stores it.

Usage: .venv/bin/python benchmarks/bench_irassi.py [--reps 30]
"""

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from refexmc.config.load import load_mission, load_vehicle  # noqa: E402
from refexmc.config.pack import mode_names, pack  # noqa: E402
from refexmc.simulate import fly  # noqa: E402

TARGET_MS = 100.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--reps", type=int, default=30)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[-1]})
    vehicle = load_vehicle(ROOT / "configs/vehicles/irassi.yaml")
    print(f"refexmc IRASSI flight benchmark, {platform.processor() or platform.machine()}, nproc {os.cpu_count()}")
    for name in ("irassi-small-angle", "irassi-large-angle"):
        mission = load_mission(ROOT / f"configs/missions/{name}.yaml")
        inputs, names = pack(vehicle, mission), mode_names(mission)
        fly(inputs, 0, 1 / 600, names)  # compile or load from the cache
        times = []
        for _ in range(args.reps):
            t0 = time.perf_counter()
            result = fly(inputs, 0, 1 / 600, names)
            times.append(1e3 * (time.perf_counter() - t0))
        q = statistics.quantiles(times, n=4)
        median = statistics.median(times)
        verdict = "PASS" if median <= TARGET_MS else "FAIL"
        steps = int(result.value("rk4_steps"))
        print(
            f"{name:20s} median {median:6.1f} ms  min {min(times):6.1f}  IQR {q[2] - q[0]:5.1f}  "
            f"({steps} RK4 steps, {1e6 * median / steps:.0f} ns each)  target <= {TARGET_MS:.0f} ms: {verdict}"
        )
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
