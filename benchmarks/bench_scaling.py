"""Whole-command cost against workers, loky and Dask, and the model that predicts many cores (issue 15).

For each backend (loky ``-j J``; Dask ``--scheduler local:J``) and each J of ``--jobs``, runs
``refexmc run campaigns/refex-mc100.yaml`` as a user does, at ``--small`` and at ``--runs`` runs,
alternating, ``--repeats`` times. From each pair of wall times:

- marginal cost per run m_J = (T_big - T_small) / (runs - small): start-up cancels;
- fixed cost F_J = T_small - small * m_J: start to first part written, plus the end;
- per-worker efficiency e_J = m_1 / (J m_J) against loky at one worker.

The model of the whole command is T(J, N) = F_J + N m_1 / (J e_J). With the fixed cost and
efficiency measured at the largest J here, it predicts the speed-up at ``--predict-jobs``
workers for ``--predict-runs`` runs, and the largest fixed cost that still gives ``--target``.

Usage: .venv/bin/python benchmarks/bench_scaling.py [--jobs 1 2] [--runs 1000] [--small 100]
       [--repeats 3] [--backends loky dask] [--predict-jobs 16] [--predict-runs 8000] [--json PATH]
"""

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_campaign import run_cli  # noqa: E402


def options(backend, jobs):
    return ("--backend", "dask", "--scheduler", f"local:{jobs}") if backend == "dask" else ()


def measure(backend, jobs, runs, small, repeats, tmp):
    """Marginal s per run and fixed s (medians over the pairs), and the pairs' wall times."""
    pairs = []
    for _ in range(repeats):
        t_small = run_cli(small, jobs, tmp / "small", options=options(backend, jobs))[0]
        t_big = run_cli(runs, jobs, tmp / "big", options=options(backend, jobs))[0]
        pairs.append((t_small, t_big))
    marginal = statistics.median((big - little) / (runs - small) for little, big in pairs)
    fixed = statistics.median(little - small * marginal for little, _ in pairs)
    return {"marginal_s": marginal, "fixed_s": fixed, "pairs_s": pairs}


def predicted_speedup(one, many, jobs, runs):
    """Whole-command speed-up of ``jobs`` workers over one for ``runs`` runs, by the model."""
    t_one = one["fixed_s"] + runs * one["marginal_s"]
    t_many = many["fixed_s"] + runs * one["marginal_s"] / (jobs * many["efficiency"])
    return t_one / t_many


def largest_fixed_cost(one, many, jobs, runs, target):
    """The fixed cost at ``jobs`` workers that still gives a ``target`` speed-up."""
    t_one = one["fixed_s"] + runs * one["marginal_s"]
    return t_one / target - runs * one["marginal_s"] / (jobs * many["efficiency"])


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--small", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--backends", nargs="+", default=["loky", "dask"], choices=["loky", "dask"])
    parser.add_argument("--predict-jobs", type=int, default=16)
    parser.add_argument("--predict-runs", type=int, default=8000)
    parser.add_argument("--target", type=float, default=12.0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    results = {
        "command": " ".join(sys.argv),
        "machine": f"{platform.node()} {os.cpu_count()} cpus, Python {platform.python_version()}",
        "load_average": os.getloadavg(),
        "measured": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        run_cli(20, 1, tmp / "warm")  # kernels in the cache, files in the page cache
        for jobs in args.jobs:  # backends alternate at each J, so that load drifts hit both
            for backend in args.backends:
                m = measure(backend, jobs, args.runs, args.small, args.repeats, tmp)
                results["measured"][f"{backend}:{jobs}"] = m
    one = results["measured"]["loky:1"]
    print(f"{results['machine']}; load average before {results['load_average'][0]:.1f}")
    print(f"{'backend:J':<10} {'marginal ms':>11} {'fixed s':>8} {'efficiency':>10} {'runs/s at N':>12}")
    for name, m in results["measured"].items():
        jobs = int(name.split(":")[1])
        m["efficiency"] = one["marginal_s"] / (jobs * m["marginal_s"])
        rate = args.runs / statistics.median(big for _, big in m["pairs_s"])
        print(f"{name:<10} {1e3 * m['marginal_s']:>11.3f} {m['fixed_s']:>8.2f} {m['efficiency']:>10.2f} {rate:>12.0f}")
    for backend in args.backends:
        if backend != "loky" and f"{backend}:{args.jobs[-1]}" in results["measured"]:
            theirs, ours = (
                results["measured"][f"{backend}:{args.jobs[-1]}"],
                results["measured"][f"loky:{args.jobs[-1]}"],
            )
            results[f"{backend}_over_loky_marginal"] = theirs["marginal_s"] / ours["marginal_s"]
            print(
                f"{backend} / loky at J={args.jobs[-1]}: marginal {theirs['marginal_s'] / ours['marginal_s']:.2f}x, "
                f"fixed {theirs['fixed_s'] - ours['fixed_s']:+.2f} s"
            )
    many = results["measured"][f"loky:{args.jobs[-1]}"]
    p, n = args.predict_jobs, args.predict_runs
    results["prediction"] = {
        "jobs": p,
        "runs": n,
        "assumed": f"fixed cost and per-worker efficiency of loky -j {args.jobs[-1]}",
        "speedup": predicted_speedup(one, many, p, n),
        "largest_fixed_s_for_target": largest_fixed_cost(one, many, p, n, args.target),
    }
    print(
        f"model: {n} runs at -j {p} (fixed {many['fixed_s']:.2f} s and efficiency {many['efficiency']:.2f} of "
        f"-j {args.jobs[-1]}): speed-up {results['prediction']['speedup']:.1f}x; {args.target:g}x needs a fixed "
        f"cost <= {results['prediction']['largest_fixed_s_for_target']:.2f} s at that efficiency"
    )
    if args.json:
        args.json.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
