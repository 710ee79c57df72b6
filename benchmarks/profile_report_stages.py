"""CPU of each stage of ``make_report(OUT)``: the process's (every thread) and the main thread's (issue 37).

On a machine shared with other work, wall times say little; the CPU seconds of a stage and of the
main thread (``time.thread_time``: what more cores cannot shorten) are what extrapolate. The
stages are module functions of ``refexmc.report`` wrapped in this process; with PROFILE, a
cProfile of the main thread is printed (its 35 costliest functions) and written there.

Usage: .venv/bin/python -P benchmarks/profile_report_stages.py OUT [PROFILE]
(-P: the working directory does not shadow PYTHONPATH, to profile another checkout's code.)
"""

import cProfile
import functools
import io
import pstats
import resource
import sys
import time

import refexmc.report as report
from refexmc.report import aggregate, data, factors, html, outputs, published, summary

STAGES = [
    (data, ["load", "read_runs_parts", "completeness", "present_columns"]),
    (summary, ["build", "campaign_metrics", "column_sections", "failure_reasons", "failure_sets", "inputs_section"]),
    (summary, ["sensitivity", "varying_parameters", "convergence", "worst_cases", "failures_section"]),
    (outputs, ["plan"]),
    (report, ["evaluate", "render_figures", "load_requirements"]),
    (aggregate, ["aggregate_histories", "history_ranges", "statistics_min_max"]),
    (html, ["page"]),
    (published, ["sections"]),
    (factors, ["factors"]),
]


def cpu():
    """CPU seconds (user + system) of this process, every thread."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def wrap(module, name, rows, depth):
    """Replace ``module.name`` by a wrapper that appends (depth, name, CPU, wall, main-thread CPU) to ``rows``."""
    function = getattr(module, name)

    @functools.wraps(function)
    def timed(*args, **kwargs):
        start = (cpu(), time.perf_counter(), time.thread_time())
        level = depth[0]
        depth[0] += 1
        try:
            return function(*args, **kwargs)
        finally:
            depth[0] -= 1
            spent = (cpu() - start[0], time.perf_counter() - start[1], time.thread_time() - start[2])
            rows.append((level, f"{module.__name__.split('.')[-1]}.{name}", *spent))

    setattr(module, name, timed)


def main():
    rows, depth = [], [0]
    for module, names in STAGES:
        for name in names:
            wrap(module, name, rows, depth)
    profile = cProfile.Profile() if len(sys.argv) > 2 else None
    start = (cpu(), time.perf_counter(), time.thread_time())
    if profile:
        profile.enable()
    report.make_report(sys.argv[1], html=True)
    if profile:
        profile.disable()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"make_report: CPU {cpu() - start[0]:.1f} s, main thread {time.thread_time() - start[2]:.1f} s, "
        f"wall {time.perf_counter() - start[1]:.1f} s, peak RSS {peak:.0f} MiB (imports before: {start[0]:.1f} s CPU)"
    )
    for level, name, seconds, wall, main_thread in sorted(rows, key=lambda row: -row[2])[:24]:
        print(f"{'  ' * level}{name:40s} CPU {seconds:7.2f}  wall {wall:7.2f}  main thread {main_thread:7.2f}")
    if profile:
        text = io.StringIO()
        pstats.Stats(profile, stream=text).sort_stats("tottime").print_stats(35)
        print(text.getvalue())
        profile.dump_stats(sys.argv[2])


if __name__ == "__main__":
    main()
