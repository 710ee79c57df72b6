"""Report time and peak memory for a finished campaign (issue 4 target: 10,000 runs at 2 Hz in <= 30 s, <= 2 GB).

Each repeat runs ``make_report(OUT)`` in a fresh subprocess (so imports and the first matplotlib
use count, as for a user) and records its wall time (from the parent) and its peak resident
memory (``ru_maxrss`` of that child alone, from ``os.wait4``; the report starts no processes of
its own). With ``--stages`` one more subprocess times the stages of ``make_report`` in-process
(each wrapped where ``make_report`` looks it up) and the peak RSS reached by the end of each.

Usage: .venv/bin/python benchmarks/bench_report.py OUT [--no-html] [--repeats 3] [--stages] [--json PATH]

Make a 10,000-run OUT first, e.g.
``.venv/bin/refexmc run campaigns/refex-mc100.yaml --runs 10000 -j 2 -o /tmp/mc10k --overwrite --no-progress``,
and from it a 100,000-run OUT with histories: ``benchmarks/make_big_out.py /tmp/mc10k /tmp/mc100k``
(``--no-histories`` for the runs table alone).
"""

import argparse
import json
import os
import platform
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

# Wraps the functions make_report reaches through module attributes; prints one JSON object:
# {"stages": [[name, seconds, calls, peak_rss_mib_after], ...], "total_s": ...}. Nested stages
# (PNG encoding inside each figure) are listed too, so the shares do not add up to 100 %.
STAGES_CHILD = """
import json, resource, sys, time
records = {}
def peak_mib():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
def timed(module, attribute, name):
    function = getattr(module, attribute)
    def wrapper(*args, **kwargs):
        records.setdefault(name, (0.0, 0, 0.0))  # listed in the order the stages start
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            seconds, calls, _ = records.get(name, (0.0, 0, 0.0))
            records[name] = (seconds + time.perf_counter() - start, calls + 1, peak_mib())
    setattr(module, attribute, wrapper)
t0 = time.perf_counter()
import refexmc.report as report
from refexmc.report import aggregate, data, summary
records["import refexmc.report (pandas, pyarrow)"] = (time.perf_counter() - t0, 1, peak_mib())
t1 = time.perf_counter()
from refexmc.report import figures, html
records["import figures (matplotlib)"] = (time.perf_counter() - t1, 1, peak_mib())
timed(data, "load", "read runs table (data.load)")
timed(summary, "build", "summary statistics (summary.build)")
timed(report, "render_figures", "all figures (render_figures, with histories)")
timed(aggregate, "aggregate_histories", "  histories: read + bin (aggregate_histories)")
for name in dir(figures):
    if name.endswith("_figure"):
        timed(figures, name, "  figure " + name)
timed(figures, "png", "    of which PNG encoding (figures.png)")
timed(html, "page", "HTML page (html.page)")
timed(report, "write_text_atomic", "write index.html + summary.json")
start = time.perf_counter()
report.make_report(sys.argv[1], html=sys.argv[2] == "html")
make_report_s = time.perf_counter() - start
stages = [[name, seconds, calls, peak] for name, (seconds, calls, peak) in records.items()]
print(json.dumps({"stages": stages, "make_report_s": make_report_s, "total_s": time.perf_counter() - t0,
                  "peak_rss_mib": peak_mib()}))
"""


def run_child(code, out, html):
    """(wall seconds, last stdout line, peak RSS MiB of this child) of ``python -c code OUT html|nohtml``."""
    start = time.perf_counter()
    proc = subprocess.Popen(
        [sys.executable, "-c", code, str(out), "html" if html else "nohtml"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    stdout, stderr = proc.stdout.read(), proc.stderr.read()  # small: a line or two, or a traceback
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    proc.stdout.close()
    proc.stderr.close()
    if proc.returncode != 0:
        sys.exit(f"report failed (exit {proc.returncode}):\n{stderr}")
    return wall, stdout.strip().splitlines()[-1], usage.ru_maxrss / 1024  # ru_maxrss: KiB on Linux


def stage_table(stages):
    """The --stages result as a Markdown table (name, seconds, share of make_report, calls, peak RSS after)."""
    lines = ["| Stage | Time | Share | Calls | Peak RSS after |", "|---|---:|---:|---:|---:|"]
    for name, seconds, calls, peak in stages["stages"]:
        share = 100 * seconds / stages["make_report_s"] if not name.startswith("import") else float("nan")
        share_text = "" if share != share else f"{share:.0f} %"
        lines.append(f"| {name} | {seconds:.2f} s | {share_text} | {calls} | {peak:.0f} MiB |")
    lines.append(f"| make_report (after imports) | {stages['make_report_s']:.2f} s | 100 % | 1 | |")
    lines.append(
        f"| whole child (imports + make_report) | {stages['total_s']:.2f} s | | | {stages['peak_rss_mib']:.0f} MiB |"
    )
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--no-html", action="store_true")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--stages", action="store_true", help="also time make_report's stages in one more child")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    html = not args.no_html
    runs_parts = sum(1 for _ in (args.out / "runs").glob("part-*.parquet"))
    history_bytes = sum(p.stat().st_size for p in (args.out / "histories").glob("part-*.parquet"))
    walls, inside, peaks = [], [], []
    for _ in range(args.repeats):
        wall, line, peak = run_child(CHILD, args.out, html)
        walls.append(wall)
        inside.append(float(line))
        peaks.append(peak)
    summary = json.loads((args.out / "report" / "summary.json").read_text())
    try:
        load = os.getloadavg()
    except OSError:
        load = None
    result = {
        "out": str(args.out),
        "runs": summary["counts"]["runs"],
        "runs_parts": runs_parts,
        "histories_mib": history_bytes / 2**20,
        "html": html,
        "figures": len(summary.get("figures", [])),
        "wall_s_median": statistics.median(walls),
        "wall_s_all": walls,
        "in_process_s_median": statistics.median(inside),
        "peak_rss_mib_max": max(peaks),
        "peak_rss_mib_all": peaks,
        "nproc": os.cpu_count(),
        "load_average_after": load,
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
        "python": platform.python_version(),
    }
    if args.stages:
        _, line, _ = run_child(STAGES_CHILD, args.out, html)
        result["stages"] = json.loads(line)
    print(json.dumps(result, indent=2))
    if args.stages:
        print(stage_table(result["stages"]))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
