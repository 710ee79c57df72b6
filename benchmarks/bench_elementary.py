"""refexmc.core.elementary against glibc's libm (numba's math.*), per function (issue 37).

Usage::

    .venv/bin/python benchmarks/bench_elementary.py [--n 1000000] [--reps 7]

Each function in a compiled loop over ``--n`` arguments of its flight range, elementary and libm
timed alternately (median of ``--reps``), in ns per call; the ratio is what a call costs more.
"""

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from refexmc._jit import jit  # noqa: E402
from refexmc.core import elementary  # noqa: E402


def _loop(function):
    @jit
    def run(x, out):
        total = 0.0
        for i in range(x.shape[0]):
            total += function(x[i])
        out[0] = total

    return run


def _loop2(function):
    @jit
    def run(y, x, out):
        total = 0.0
        for i in range(x.shape[0]):
            total += function(y[i], x[i])
        out[0] = total

    return run


def _libm_sin(x):
    return math.sin(x)


def _libm_cos(x):
    return math.cos(x)


def _libm_tan(x):
    return math.tan(x)


def _libm_exp(x):
    return math.exp(x)


def _libm_log(x):
    return math.log(x)


def _libm_asin(x):
    return math.asin(x)


def _libm_acos(x):
    return math.acos(x)


def _libm_atan2(y, x):
    return math.atan2(y, x)


def _sincos_libm(x):
    return math.sin(x) + math.cos(x)


def _sincos_elementary(x):
    s, c = elementary.sincos(x)
    return s + c


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--reps", type=int, default=7)
    args = parser.parse_args()
    rng = np.random.default_rng(37)
    n = args.n
    angle = rng.uniform(-2 * math.pi, 2 * math.pi, n)
    cases = [
        ("sin", angle, elementary.sin, _libm_sin),
        ("cos", angle, elementary.cos, _libm_cos),
        ("tan", angle, elementary.tan, _libm_tan),
        ("sin+cos (sincos)", angle, _sincos_elementary, _sincos_libm),
        ("exp", rng.uniform(-20.0, 20.0, n), elementary.exp, _libm_exp),
        ("log", rng.uniform(1e-3, 1e3, n), elementary.log, _libm_log),
        ("asin", rng.uniform(-1.0, 1.0, n), elementary.asin, _libm_asin),
        ("acos", rng.uniform(-1.0, 1.0, n), elementary.acos, _libm_acos),
    ]
    out = np.zeros(1)
    print(f"{'function':18s} {'elementary ns':>14s} {'libm ns':>9s} {'ratio':>6s}")
    for name, x, mine, libm in cases:
        loops = [_loop(mine if hasattr(mine, "py_func") else jit(mine)), _loop(jit(libm))]
        times = [[], []]
        for loop in loops:
            loop(x[:10], out)  # compile
        for _ in range(args.reps):
            for k, loop in enumerate(loops):
                start = time.perf_counter()
                loop(x, out)
                times[k].append((time.perf_counter() - start) / n * 1e9)
        a, b = statistics.median(times[0]), statistics.median(times[1])
        print(f"{name:18s} {a:14.1f} {b:9.1f} {a / b:6.2f}")
    y, x = rng.uniform(-1, 1, n), rng.uniform(-1, 1, n)
    loops = [_loop2(elementary.atan2), _loop2(jit(_libm_atan2))]
    times = [[], []]
    for loop in loops:
        loop(y[:10], x[:10], out)
    for _ in range(args.reps):
        for k, loop in enumerate(loops):
            start = time.perf_counter()
            loop(y, x, out)
            times[k].append((time.perf_counter() - start) / n * 1e9)
    a, b = statistics.median(times[0]), statistics.median(times[1])
    print(f"{'atan2':18s} {a:14.1f} {b:9.1f} {a / b:6.2f}")


if __name__ == "__main__":
    main()
