"""The SPORE deorbit campaign (issue 13): the whole 1000-run command on this machine's cores.

Runs ``refexmc run campaigns/spore-deorbit-iss.yaml -j J`` as a subprocess, as a user does (warm
kernel cache: one untimed 20-run campaign first), and measures:

1. the whole command at ``-j 2`` (``--repeats`` times, median) and once at ``-j 1``: wall time and
   the peak resident memory of the process tree. Target: 1000 runs in < 2 min on 2 cores.
2. in-process, for scale: one SPORE flight (``fly_chunk`` of 50 dispersed runs, per run, after a
   first untimed chunk) and the nominal plan (bisection + phasing, ``config.deorbit.plan``).

Usage: .venv/bin/python benchmarks/bench_spore.py [--repeats 3] [--json PATH]
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_campaign import REFEXMC, run_cli  # noqa: E402

CAMPAIGN = ROOT / "campaigns" / "spore-deorbit-iss.yaml"
TARGET_S = 120.0

_PROBE = """
import json, sys, time
from refexmc.campaign.chunk import fly_chunk
from refexmc.campaign.run import resolve_campaign
from refexmc.config import deorbit
_, campaign = resolve_campaign(sys.argv[1], runs=101)
fly_chunk(campaign, [0])  # kernels loaded and the plan made: only flying is timed below
t0 = time.perf_counter()
fly_chunk(campaign, range(1, 51))
flight = (time.perf_counter() - t0) / 50
vehicle, mission = campaign["vehicle"], campaign["mission"]
fsw = vehicle["flight_software"]
t0 = time.perf_counter()
deorbit.plan(vehicle, mission, 1.0 / fsw["control_rate_hz"], 1.0 / fsw["burn_guidance"]["rate_hz"])
print(json.dumps({"flight_s": flight, "plan_s": time.perf_counter() - t0}))
"""


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "spore"
        subprocess.run(
            [*REFEXMC, "run", str(CAMPAIGN), "--runs", "20", "-o", str(out), "--overwrite", "--no-progress"],
            cwd=ROOT,
            check=True,
            capture_output=True,
        )
        two = [run_cli(1000, 2, out, CAMPAIGN) for _ in range(args.repeats)]
        one = run_cli(1000, 1, out, CAMPAIGN)
    probe = json.loads(
        subprocess.run(
            [sys.executable, "-c", _PROBE, str(CAMPAIGN)], cwd=ROOT, check=True, capture_output=True, text=True
        ).stdout
    )
    result = {
        "machine": {"nproc": os.cpu_count(), "python": platform.python_version(), "load": os.getloadavg()},
        "j2_wall_s": [w for w, _, _ in two],
        "j2_wall_median_s": statistics.median(w for w, _, _ in two),
        "j2_peak_tree_rss_mib": max(r for _, r, _ in two),
        "j1_wall_s": one[0],
        "j1_peak_tree_rss_mib": one[1],
        **probe,
    }
    median, verdict = result["j2_wall_median_s"], "PASS" if result["j2_wall_median_s"] < TARGET_S else "FAIL"
    print(
        f"1000 runs -j 2: {', '.join(f'{w:.1f}' for w in result['j2_wall_s'])} s, median {median:.1f} s "
        f"({verdict} < {TARGET_S:.0f} s), peak RSS {result['j2_peak_tree_rss_mib']:.0f} MiB"
    )
    print(f"1000 runs -j 1: {one[0]:.1f} s, peak RSS {one[1]:.0f} MiB; speed-up -j 2 / -j 1 {one[0] / median:.2f}x")
    print(f"one flight in-process: {1e3 * probe['flight_s']:.1f} ms; the nominal plan: {probe['plan_s']:.2f} s")
    print(f"load average at the end: {os.getloadavg()}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
