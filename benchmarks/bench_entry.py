"""The closed-loop X-38 entry (core.entry_flight, issue 24): time per entry on one core.

Usage::

    .venv/bin/python benchmarks/bench_entry.py [--repeats N]

Flies tests/test_entry_flight.py's entry (121.9 km to Mach 2, 10 Hz control) nominal and with the
right flap blocked at 14 deg (without and with a 30 ms RCS delay), pinned to one CPU, after a
warm-up call; prints the median and the best of N of ``core.entry_flight.fly`` alone (the vehicle
file is read once, before).
Target (issue 24): one entry <= 50 ms. The first call's time (compile or cache load) is printed
too.
"""

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

TARGET_MS = 50.0


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[-1]})
    import numpy as np
    import test_entry_flight as flight

    from refexmc.core import entry_flight as ef

    print(f"load average: {os.getloadavg()[0]:.2f} (1 min)")
    cases = (
        ("nominal", None, 0.0),
        ("flap blocked at 14 deg", ("right", 14.0), 0.0),
        ("flap blocked at 14 deg, 30 ms RCS delay", ("right", 14.0), 0.03),  # two RK4 steps per period
    )
    for name, blocked, delay_s in cases:
        if delay_s > 0.0 and not hasattr(ef, "CT_RCS_DELAY_S"):  # a commit before the delay existed
            continue
        flown, initial = flight.prepare(blocked)
        if delay_s > 0.0:
            flown.control[ef.CT_RCS_DELAY_S] = delay_s
        wk, history, summary = ef.work(), np.zeros((3000, ef.HISTORY_COLUMNS)), np.zeros(ef.SUMMARY_SIZE)
        start = time.perf_counter()
        ef.fly(flown, wk, initial, history, summary)
        first = time.perf_counter() - start
        times = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            ef.fly(flown, wk, initial, history, summary)
            times.append(time.perf_counter() - start)
        median_ms, best_ms = 1e3 * statistics.median(times), 1e3 * min(times)
        verdict = "PASS" if median_ms <= TARGET_MS else "FAIL"
        print(
            f"{name}: first call {first:.2f} s; median {median_ms:.1f} ms, best {best_ms:.1f} ms per entry "
            f"({int(summary[8])} control periods, {summary[0]:.0f} s flown, {summary[1]:.2f} kg RCS) "
            f"target <= {TARGET_MS:.0f} ms: {verdict}"
        )


if __name__ == "__main__":
    main()
