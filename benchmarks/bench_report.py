"""Report time and peak memory for a finished campaign (issue 4 target: 10,000 runs at 2 Hz in <= 30 s, <= 2 GB).

Runs ``make_report(OUT)`` in a fresh subprocess (so imports and the first matplotlib use count,
as for a user) and reports its wall time and peak resident memory (``ru_maxrss`` of the child).

Usage: .venv/bin/python benchmarks/bench_report.py OUT [--no-html] [--repeats 3] [--json PATH]

Make a 10,000-run OUT first, e.g.
``.venv/bin/refexmc run campaigns/refex-mc100.yaml --runs 10000 -o /tmp/mc10k --overwrite``.
"""

import argparse
import json
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

CHILD = """
import sys, time
t0 = time.perf_counter()
from refexmc.report import make_report
result = make_report(sys.argv[1], html=sys.argv[2] == "html")
print(time.perf_counter() - t0)
"""


def measure(out, html):
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", CHILD, str(out), "html" if html else "nohtml"], capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"report failed:\n{proc.stderr}")
    # ru_maxrss of RUSAGE_CHILDREN is the largest child so far (KiB on Linux)
    peak_mib = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return wall, float(proc.stdout.strip().splitlines()[-1]), peak_mib


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--no-html", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    runs = sum(1 for _ in (args.out / "runs").glob("part-*.parquet"))
    history_bytes = sum(p.stat().st_size for p in (args.out / "histories").glob("part-*.parquet"))
    walls, inside = [], []
    peak = 0.0
    for _ in range(args.repeats):
        wall, in_process, peak = measure(args.out, not args.no_html)
        walls.append(wall)
        inside.append(in_process)
    summary = json.loads((args.out / "report" / "summary.json").read_text())
    result = {
        "out": str(args.out),
        "runs": summary["counts"]["runs"],
        "runs_parts": runs,
        "histories_mib": history_bytes / 2**20,
        "html": not args.no_html,
        "wall_s_median": statistics.median(walls),
        "wall_s_all": walls,
        "in_process_s_median": statistics.median(inside),
        "peak_rss_mib": peak,
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
        "python": platform.python_version(),
    }
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
