"""How `refexmc report` time, CPU and peak memory grow with the number of runs (issue 37 point 5).

From one flown, complete OUT (``SRC``, its run count a multiple of its chunk size), builds bigger
OUTs of ``--sizes`` runs by repeating SRC's runs table and histories with shifted run ids
(``benchmarks/make_big_out.py``: the report reads them as any other OUT; sizes above
``--histories-up-to`` repeat the runs table only), then reports each ``--repeats`` times in fresh
subprocesses: wall time from the parent, CPU time (user + system) and peak RSS of the child from
``os.wait4``. With ``--before ROOT`` each repeat runs the report of another checkout's code
(``PYTHONPATH=ROOT``, this interpreter) right before this one's, so that the ratios compare runs
made under the same load. Also prints the Parquet bytes per run of SRC's runs table and histories.

Usage: .venv/bin/python benchmarks/bench_report_scale.py SRC --work /tmp/scale \
          [--sizes 10000 100000] [--histories-up-to 100000] [--repeats 3] [--before /path/to/main] [--json PATH]

E.g. SRC = ``refexmc run campaigns/refex-mc100.yaml --runs 2000 -j 2 -o /tmp/mc2k --no-progress``.
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

sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_big_out import make_big_out  # noqa: E402

from refexmc.campaign import storage  # noqa: E402

CHILD = """
import sys
from refexmc.report import make_report
make_report(sys.argv[1], html=True)
"""
CHECK = """
import sys
import refexmc
from pathlib import Path
assert not sys.argv[2] or Path(refexmc.__file__).is_relative_to(sys.argv[2]), f"{refexmc.__file__}: not {sys.argv[2]}"
"""


def report_once(out, root=None):
    """(wall s, CPU s, peak RSS MiB) of ``make_report(out)`` in a fresh child (``root``'s code if given)."""
    env = dict(os.environ)
    if root is not None:
        env["PYTHONPATH"] = str(root)
    start = time.perf_counter()
    proc = subprocess.Popen(
        # -P: not the working directory first on sys.path, where it would win over PYTHONPATH
        [sys.executable, "-P", "-c", CHECK + CHILD, str(out), str(root or "")],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    stderr = proc.stderr.read()
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.stderr.close()
    if os.waitstatus_to_exitcode(status) != 0:
        sys.exit(f"report of {out} failed:\n{stderr.decode()}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def bytes_per_run(out):
    """{folder: Parquet bytes per run} of OUT's runs and histories."""
    runs = int(storage.read_manifest(out)["runs"])
    return {
        folder: sum(p.stat().st_size for p in (Path(out) / folder).glob("part-*.parquet")) / runs
        for folder in ("runs", "histories")
    }


def big_out(src, work, size, histories):
    """The OUT of ``size`` runs made from SRC (reused when it is there already)."""
    src_runs = int(storage.read_manifest(src)["runs"])
    if size % src_runs:
        sys.exit(f"size {size} is not a multiple of SRC's {src_runs} runs")
    dest = Path(work) / f"{size}{'' if histories else '-runs-only'}"
    if dest.exists() and storage.read_manifest(dest).get("runs") == size:
        return dest
    runs, parts, seconds = make_big_out(src, dest, size // src_runs, histories=histories, overwrite=True)
    print(f"made {dest}: {runs} runs, {parts} parts, {seconds:.0f} s", file=sys.stderr)
    return dest


def median_of(samples, index):
    return statistics.median(s[index] for s in samples)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("src", type=Path)
    parser.add_argument("--work", type=Path, required=True)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--histories-up-to", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--before", type=Path, help="another checkout whose report runs before each of this one's")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    result = {
        "src": str(args.src),
        "bytes_per_run": bytes_per_run(args.src),
        "nproc": os.cpu_count(),
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
        "load_average_start": os.getloadavg(),
        "sizes": [],
    }
    for size in args.sizes:
        histories = size <= args.histories_up_to
        out = big_out(args.src, args.work, size, histories)
        after, before = [], []
        for _ in range(args.repeats):
            if args.before is not None:
                before.append(report_once(out, args.before))
            after.append(report_once(out))
        row = {"runs": size, "histories": histories, "after": after, "before": before}
        for name, samples in (("after", after), ("before", before)):
            if samples:
                row[name + "_median"] = {
                    "wall_s": median_of(samples, 0),
                    "cpu_s": median_of(samples, 1),
                    "peak_rss_mib": max(s[2] for s in samples),
                }
        if before:
            row["wall_ratio_after_before"] = [a[0] / b[0] for a, b in zip(after, before, strict=True)]
        result["sizes"].append(row)
        print(json.dumps(row), flush=True)
    result["load_average_end"] = os.getloadavg()
    print(json.dumps(result, indent=2))
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")


if __name__ == "__main__":
    main()
