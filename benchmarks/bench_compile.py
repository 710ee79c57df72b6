"""Cold compile and warm load of each vehicle family's flight kernel (issue 22).

Usage::

    .venv/bin/python benchmarks/bench_compile.py [--json PATH] [--warm-reps N] [--campaigns A.yaml B.yaml ...]
        [--python OTHER/.venv/bin/python --root OTHER]   # the same on another checkout (before/after)

Per campaign (default: nominal, spore-deorbit-iss, irassi-fine-pointing, generic-slew), in fresh
interpreters:

- ``cold``: import + load and pack the campaign + first ``simulate.fly`` with an empty
  ``NUMBA_CACHE_DIR`` (everything the family's kernel reaches is compiled). Wall time, and the
  child's CPU time (user + system, from ``resource``): on a shared machine the CPU time moves less
  with the load than the wall time does.
- ``warm``: the same with the cache the cold child filled (compiled code loaded), median of
  ``--warm-reps``.
- ``after_others``: cold again, in a cache where every *other* campaign's family was compiled
  first: what the disk cache of one family does for another (with one kernel per family, nothing
  but what they share: the small jitted helpers of unchanged signatures).

``--python``/``--root`` run the children with another interpreter on another checkout (its
``refexmc`` first on ``PYTHONPATH``): the child uses only ``load_campaign``, ``pack`` and
``simulate.fly``, which every version has, so that one command gives before and after.
Takes about 3 minutes per campaign on 2 quiet cores (cold compiles of 10-30 s each).
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGNS = (
    "campaigns/nominal.yaml",
    "campaigns/spore-deorbit-iss.yaml",
    "campaigns/irassi-fine-pointing.yaml",
    "campaigns/generic-slew.yaml",
)

_CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from refexmc.config.load import load_campaign
from refexmc.config.pack import pack
from refexmc.simulate import fly
t1 = time.perf_counter()
c = load_campaign(sys.argv[1])
inputs = pack(c["vehicle"], c["mission"])
t2 = time.perf_counter()
r = fly(inputs)
t3 = time.perf_counter()
ru = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"import_s": t1 - t0, "load_pack_s": t2 - t1, "first_fly_s": t3 - t2, "total_s": t3 - t0,
                  "cpu_s": ru.ru_utime + ru.ru_stime, "success": bool(r.success)}))
"""


def _child(python, root, campaign, cache_dir):
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(cache_dir)
    env.pop("REFEXMC_DISABLE_JIT", None)
    env["PYTHONPATH"] = str(root) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    t0 = time.perf_counter()
    proc = subprocess.run(
        [python, "-c", _CHILD, str(Path(root) / campaign)], cwd=root, env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"child failed for {campaign}:\n{proc.stderr}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process_wall_s"] = wall
    return out


def _load():
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


def bench(python, root, campaigns, warm_reps, others):
    results = {}
    for campaign in campaigns:
        cache = Path(tempfile.mkdtemp(prefix="refexmc-bench-compile-"))
        try:
            load_before = _load()
            cold = _child(python, root, campaign, cache)
            files = sum(1 for p in cache.rglob("*") if p.is_file())
            warm = [_child(python, root, campaign, cache) for _ in range(warm_reps)]
            row = {
                "cold": cold,
                "cold_load_average": load_before,
                "cache_files": files,
                "warm_total_s": sorted(w["total_s"] for w in warm)[len(warm) // 2],
                "warm_first_fly_s": sorted(w["first_fly_s"] for w in warm)[len(warm) // 2],
                "warm_cpu_s": sorted(w["cpu_s"] for w in warm)[len(warm) // 2],
            }
        finally:
            shutil.rmtree(cache, ignore_errors=True)
        if others:
            cache = Path(tempfile.mkdtemp(prefix="refexmc-bench-compile-"))
            try:
                for other in campaigns:
                    if other != campaign:
                        _child(python, root, other, cache)
                row["after_others"] = _child(python, root, campaign, cache)
            finally:
                shutil.rmtree(cache, ignore_errors=True)
        results[campaign] = row
        print_row(campaign, row)
    return results


def print_row(campaign, row):
    cold = row["cold"]
    line = (
        f"{Path(campaign).stem:24s} cold {cold['total_s']:6.1f} s wall ({cold['cpu_s']:5.1f} s CPU, first fly"
        f" {cold['first_fly_s']:5.1f} s, load avg {row['cold_load_average']:.1f}); warm {row['warm_total_s']:5.2f} s"
        f" (first fly {row['warm_first_fly_s']:.2f} s, {row['warm_cpu_s']:.2f} s CPU)"
    )
    if "after_others" in row:
        a = row["after_others"]
        line += f"; cold after the others {a['total_s']:.1f} s ({a['cpu_s']:.1f} s CPU)"
    print(line, flush=True)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, help="also write all numbers to this JSON file")
    parser.add_argument("--warm-reps", type=int, default=3)
    parser.add_argument("--campaigns", nargs="+", default=list(CAMPAIGNS))
    parser.add_argument("--python", default=sys.executable, help="interpreter of the children")
    parser.add_argument("--root", type=Path, default=ROOT, help="checkout whose refexmc the children import")
    parser.add_argument("--others", action="store_true", help="also: cold after the other families were compiled")
    args = parser.parse_args(argv)
    root = args.root.resolve()
    commit = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    print(f"refexmc compile per family: {root} at {commit.stdout.strip()}, nproc {os.cpu_count()}", flush=True)
    results = bench(args.python, root, args.campaigns, args.warm_reps, args.others)
    if args.json:
        args.json.write_text(
            json.dumps({"root": str(root), "commit": commit.stdout.strip(), "results": results}, indent=2)
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
