"""Flight-kernel benchmarks (issue 2): run time, integrator overhead, compile time, CLI start-up.

Usage::

    .venv/bin/python benchmarks/bench_flight.py [--json PATH] [--reps N] [--quick]

Four measurements, all in one invocation so that ratios come from one process and one machine
state (absolute times drift on a shared machine, ratios much less):

1. ``flight``: one nominal flight (``campaigns/nominal.yaml``) through ``refexmc.simulate.fly``
   after compilation; median, min and IQR over ``--reps`` repetitions, pinned to one CPU.
   Target: median <= 25 ms.
2. ``bare_rk4``: the same number of attitude RK4 steps as that flight took
   (``summary["rk4_steps"]``), through ``refexmc.core.dynamics.rk4_step`` with the same inertia
   and a constant torque, in a small kernel defined here. Flight and bare RK4 are timed
   alternately in the same loop. Target: median(flight) / median(bare RK4) <= 3.
3. ``compile``: import + first ``fly`` in a fresh interpreter with an empty ``NUMBA_CACHE_DIR``
   (cold: everything is compiled), then again in fresh interpreters with the same, now filled,
   directory (warm: compiled code loaded from the cache). No target; shows what the cache saves.
4. ``cli``: wall time of ``refexmc run campaigns/nominal.yaml -o TMP/out --overwrite`` with a warm
   cache (after one untimed run), median of 5. Target: < 3 s.

Only the standard library and numpy (plus refexmc itself). Takes about 20 s (the cold compile is 11 s of it).
"""

import argparse
import datetime
import hashlib
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# Child processes get the environment as it was given to us; this process runs single-threaded
# (the flight kernel is serial; keep BLAS/OpenMP pools out of the timing).
_ORIGINAL_ENV = dict(os.environ)
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from refexmc._jit import jit  # noqa: E402
from refexmc.core import dynamics  # noqa: E402

CAMPAIGN = "campaigns/nominal.yaml"
TARGET_FLIGHT_MS = 25.0
TARGET_RATIO = 3.0
TARGET_CLI_S = 3.0

# Child program for the compile-time benchmark: prints one JSON line of phase times (s).
_CHILD = r"""
import json, sys, time
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
fly(inputs)
t4 = time.perf_counter()
print(json.dumps({"import_s": t1 - t0, "load_pack_s": t2 - t1, "first_fly_s": t3 - t2,
                  "second_fly_s": t4 - t3, "import_plus_first_fly_s": (t1 - t0) + (t3 - t2),
                  "rk4_steps": int(r.value("rk4_steps")), "success": bool(r.success)}))
"""


@jit
def bare_rk4(x, x0, n_steps, h, torque, inertia, inertia_inv, work):
    """``n_steps`` RK4 steps of length ``h`` from ``x0`` under a constant body torque; state in ``x``."""
    for i in range(x0.shape[0]):
        x[i] = x0[i]
    for _ in range(n_steps):
        dynamics.rk4_step(x, h, torque, torque, inertia, inertia_inv, work)
    return x[0]


# --- statistics and machine ------------------------------------------------------------------


def stats_ms(seconds):
    """Median, min, max, quartiles, IQR and n of a sample of durations, in ms."""
    a = np.asarray(seconds) * 1e3
    q1, med, q3 = np.percentile(a, [25, 50, 75])
    return {
        "n": int(a.size),
        "median_ms": float(med),
        "min_ms": float(a.min()),
        "max_ms": float(a.max()),
        "q1_ms": float(q1),
        "q3_ms": float(q3),
        "iqr_ms": float(q3 - q1),
    }


def machine_info():
    model = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    import numba

    try:  # GNU nproc honours OMP_NUM_THREADS, so ask it with the original environment
        nproc = subprocess.run(["nproc"], capture_output=True, text=True, check=True, env=_ORIGINAL_ENV).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        nproc = str(os.cpu_count())
    core = hashlib.sha256()
    for path in sorted((ROOT / "refexmc").rglob("*.py")):
        core.update(path.relative_to(ROOT).as_posix().encode() + b"\0" + path.read_bytes())
    return {
        "date": datetime.date.today().isoformat(),
        "nproc": nproc,
        "cpu_model": model,
        "platform": platform.platform(),
        "python": platform.python_version(),
        "numba": numba.__version__,
        "numpy": np.__version__,
        "refexmc_commit": _git_commit(),
        "refexmc_sources_sha256": core.hexdigest()[:12],
    }


def _git_commit():
    try:
        out = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "-C", str(ROOT), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        return out + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


# --- 1 and 2: flight vs bare RK4, same process ------------------------------------------------


def bench_flight_vs_rk4(reps, cpu):
    from refexmc.config.load import load_campaign
    from refexmc.config.pack import pack
    from refexmc.core import flight as flight_module
    from refexmc.core import layout as L
    from refexmc.simulate import fly, history_every

    campaign = load_campaign(ROOT / CAMPAIGN)
    inputs = pack(campaign["vehicle"], campaign["mission"])
    run_flight = flight_module.kernel(*flight_module.family(inputs))  # the campaign's family kernel

    t0 = time.perf_counter()
    result = fly(inputs)  # compiles, or loads from the numba cache
    first_call_s = time.perf_counter() - t0
    n_steps = int(result.value("rk4_steps"))
    t_end = float(result.value("t_end_s"))
    if not result.success:
        raise RuntimeError(f"nominal flight failed ({result.failure_reason}); benchmark meaningless")

    inertia = inputs.vehicle[L.V_INERTIA : L.V_INERTIA + 9].copy().reshape((3, 3))
    inertia_inv = np.linalg.inv(inertia)
    x0 = np.zeros(dynamics.STATE_SIZE)
    x0[3] = 1.0
    x0[4:7] = inputs.mission[L.M_SEP_RATES : L.M_SEP_RATES + 3]
    x = np.empty_like(x0)
    work = np.empty((8, dynamics.STATE_SIZE))
    torque = np.array([0.02, -0.01, 0.015])  # N m, small enough that the rates stay moderate
    h = t_end / n_steps  # the flight's mean step
    t0 = time.perf_counter()
    bare_rk4(x, x0, n_steps, h, torque, inertia, inertia_inv, work)
    bare_first_call_s = time.perf_counter() - t0
    if not np.all(np.isfinite(x)):
        raise RuntimeError("bare RK4 state is not finite")

    for _ in range(3):  # warm caches and branch predictors
        fly(inputs)
        bare_rk4(x, x0, n_steps, h, torque, inertia, inertia_inv, work)

    # The kernel alone, outputs preallocated: fly() minus this is the Python wrapper + dispatch.
    every = history_every(inputs, campaign["output"]["history_rate_hz"])
    summary = np.zeros(L.summary_size(inputs.modes.shape[0]))
    pulses = np.zeros(inputs.thrusters.shape[0], dtype=np.int64)
    history = np.zeros((result.history.shape[0] + 3, result.history.shape[1]))  # the family's width
    kernel_args = (inputs, np.int64(0), np.int64(every), summary, pulses, history)
    try:  # since issue 35 the kernel also takes the pointing requirements' record (none here)
        from refexmc.core.pointing import empty_record

        kernel_args += (empty_record(),)
    except ImportError:  # a version before it
        pass
    run_flight(*kernel_args)

    flight_s, bare_s, kernel_s = [], [], []
    steps_seen = set()
    for _ in range(reps):  # alternate, so that drift hits all samples alike
        t0 = time.perf_counter()
        r = fly(inputs)
        t1 = time.perf_counter()
        bare_rk4(x, x0, n_steps, h, torque, inertia, inertia_inv, work)
        t2 = time.perf_counter()
        run_flight(*kernel_args)
        t3 = time.perf_counter()
        flight_s.append(t1 - t0)
        bare_s.append(t2 - t1)
        kernel_s.append(t3 - t2)
        steps_seen.add(int(r.value("rk4_steps")))
        steps_seen.add(int(summary[L.S_RK4_STEPS]))
    if steps_seen != {n_steps}:
        raise RuntimeError(f"rk4_steps changed between runs: {sorted(steps_seen)}")

    flight = stats_ms(flight_s)
    bare = stats_ms(bare_s)
    kernel = stats_ms(kernel_s)
    pair_ratios = np.asarray(flight_s) / np.asarray(bare_s)
    ratio = flight["median_ms"] / bare["median_ms"]
    control_steps = int(round(t_end / inputs.fsw[L.F_CONTROL_PERIOD]))
    return {
        "flight": {
            **flight,
            "cpu": cpu,
            "first_call_in_process_s": first_call_s,
            "rk4_steps": n_steps,
            "control_steps": control_steps,
            "t_end_s": t_end,
            "us_per_control_step": flight["median_ms"] * 1e3 / control_steps,
            "target_median_ms": TARGET_FLIGHT_MS,
            "pass": flight["median_ms"] <= TARGET_FLIGHT_MS,
        },
        "run_flight_kernel_only": {**kernel, "wrapper_overhead_ms": flight["median_ms"] - kernel["median_ms"]},
        "bare_rk4": {
            **bare,
            "first_call_in_process_s": bare_first_call_s,
            "n_steps": n_steps,
            "h_s": h,
            "torque_n_m": torque.tolist(),
            "ns_per_step": bare["median_ms"] * 1e6 / n_steps,
        },
        "ratio": {
            "flight_over_bare_rk4": ratio,
            "pairwise_median": float(np.median(pair_ratios)),
            "pairwise_min": float(pair_ratios.min()),
            "pairwise_max": float(pair_ratios.max()),
            "target": TARGET_RATIO,
            "pass": ratio <= TARGET_RATIO,
        },
    }


# --- 3: compile time, fresh interpreters -------------------------------------------------------


def _child_env(cache_dir):
    env = dict(_ORIGINAL_ENV)
    env["NUMBA_CACHE_DIR"] = str(cache_dir)
    env.pop("REFEXMC_DISABLE_JIT", None)
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return env


def _run_child(cache_dir):
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", _CHILD, CAMPAIGN],
        cwd=ROOT,
        env=_child_env(cache_dir),
        capture_output=True,
        text=True,
        timeout=600,
    )
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"compile-time child failed:\n{proc.stderr}")
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    out["process_wall_s"] = wall
    return out


def bench_compile(warm_reps):
    cache_dir = Path(tempfile.mkdtemp(prefix="refexmc-numba-cache-"))
    try:
        cold = _run_child(cache_dir)
        n_files = sum(1 for p in cache_dir.rglob("*") if p.is_file())
        warm_runs = [_run_child(cache_dir) for _ in range(warm_reps)]
        keys = ("import_s", "load_pack_s", "first_fly_s", "import_plus_first_fly_s", "process_wall_s")
        warm = {k: float(np.median([w[k] for w in warm_runs])) for k in keys}
        warm["n"] = warm_reps
        return {
            "cold": cold,
            "warm_median": warm,
            "cache_files_written": n_files,
            "saved_s": cold["import_plus_first_fly_s"] - warm["import_plus_first_fly_s"],
            "speedup": cold["import_plus_first_fly_s"] / warm["import_plus_first_fly_s"],
        }
    finally:
        shutil.rmtree(cache_dir, ignore_errors=True)


# --- 4: CLI start-up ---------------------------------------------------------------------------


def cli_command():
    """The console script next to this interpreter, else the same entry point through -c."""
    script = Path(sys.executable).parent / "refexmc"
    if script.exists():
        return [str(script)], str(script.relative_to(ROOT)) if script.is_relative_to(ROOT) else str(script)
    entry = "from refexmc.cli import main; main()"
    return [sys.executable, "-c", entry], f"python -c '{entry}'"


def cli_available():
    cli = ROOT / "refexmc" / "cli.py"
    return cli.exists() and "def run(" in cli.read_text()


def bench_cli(reps):
    if not cli_available():
        return {"measured": False, "reason": "refexmc/cli.py has no run command yet"}
    prefix, shown = cli_command()
    tmp = Path(tempfile.mkdtemp(prefix="refexmc-bench-cli-"))
    env = dict(_ORIGINAL_ENV)
    env.pop("REFEXMC_DISABLE_JIT", None)
    env["PYTHONPATH"] = str(ROOT) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    argv = prefix + ["run", CAMPAIGN, "-o", str(tmp / "out"), "--overwrite"]

    def once():
        t0 = time.perf_counter()
        proc = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
        wall = time.perf_counter() - t0
        if proc.returncode != 0:
            raise RuntimeError(f"CLI failed (rc {proc.returncode}):\n{proc.stdout}\n{proc.stderr}")
        return wall, proc.stdout

    def help_once():
        t0 = time.perf_counter()
        subprocess.run(prefix + ["--help"], cwd=ROOT, env=env, capture_output=True, check=True, timeout=120)
        return time.perf_counter() - t0

    def bare_python_once():
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", "pass"], env=env, capture_output=True, check=True, timeout=60)
        return time.perf_counter() - t0

    try:
        warmup_s, stdout = once()  # fills or refreshes the default numba cache; not counted
        walls = [once()[0] for _ in range(reps)]
        helps = [help_once() for _ in range(3)]
        pythons = [bare_python_once() for _ in range(3)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    med = float(np.median(walls))
    return {
        "measured": True,
        "command": f"{shown} run {CAMPAIGN} -o <tmpdir>/out --overwrite",
        "warmup_s": warmup_s,
        "walls_s": walls,
        "median_s": med,
        "min_s": float(min(walls)),
        "max_s": float(max(walls)),
        "help_median_s": float(np.median(helps)),
        "python_startup_median_s": float(np.median(pythons)),
        "first_stdout_line": stdout.strip().splitlines()[0] if stdout.strip() else "",
        "target_s": TARGET_CLI_S,
        "pass": med < TARGET_CLI_S,
    }


# --- report ------------------------------------------------------------------------------------


def _verdict(ok):
    return "PASS" if ok else "FAIL"


def print_report(res):
    m = res["machine"]
    print(
        f"refexmc flight benchmarks  {m['date']}  commit {m['refexmc_commit']}"
        f"  (refexmc/**.py sha256 {m['refexmc_sources_sha256']})"
    )
    print(f"  {m['cpu_model']}, nproc {m['nproc']}; Python {m['python']}, numba {m['numba']}, numpy {m['numpy']}")
    f, b, r = res["flight"], res["bare_rk4"], res["ratio"]
    print()
    print(f"{'benchmark':34s} {'median':>10s} {'min':>10s} {'IQR':>10s} {'target':>10s}  result")
    cpu = f"cpu {f['cpu']}" if f["cpu"] is not None else "unpinned"
    print(
        f"{'1 nominal flight (fly)':34s} {f['median_ms']:8.2f}ms {f['min_ms']:8.2f}ms {f['iqr_ms']:8.2f}ms"
        f" {'<= ' + format(TARGET_FLIGHT_MS, 'g') + 'ms':>10s}  {_verdict(f['pass'])}"
    )
    kk = res["run_flight_kernel_only"]
    print(
        f"{'  run_flight only (no fly wrapper)':34s} {kk['median_ms']:8.2f}ms {kk['min_ms']:8.2f}ms"
        f" {kk['iqr_ms']:8.2f}ms"
    )
    print(f"{'2 bare RK4, same steps':34s} {b['median_ms']:8.3f}ms {b['min_ms']:8.3f}ms {b['iqr_ms']:8.3f}ms {'':>10s}")
    print(
        f"{'2 ratio flight / bare RK4':34s} {r['flight_over_bare_rk4']:9.1f}x {'':>10s} {'':>10s}"
        f" {'<= ' + format(TARGET_RATIO, 'g') + 'x':>10s}  {_verdict(r['pass'])}"
    )
    print(
        f"    n = {f['n']} alternating pairs, {cpu}; {f['rk4_steps']} RK4 steps "
        f"({b['ns_per_step']:.0f} ns each bare), {f['control_steps']} control steps "
        f"({f['us_per_control_step']:.2f} us each in the flight); pairwise ratio median "
        f"{r['pairwise_median']:.1f}x [{r['pairwise_min']:.1f}, {r['pairwise_max']:.1f}]"
    )
    c = res.get("compile")
    if c:
        cold, warm = c["cold"], c["warm_median"]
        print(
            f"{'3 import + first fly, cold cache':34s} {cold['import_plus_first_fly_s']:9.2f}s"
            f"   (import {cold['import_s']:.2f}s, first fly {cold['first_fly_s']:.2f}s,"
            f" process {cold['process_wall_s']:.2f}s)"
        )
        print(
            f"{'3 import + first fly, warm cache':34s} {warm['import_plus_first_fly_s']:9.2f}s"
            f"   (import {warm['import_s']:.2f}s, first fly {warm['first_fly_s']:.2f}s,"
            f" process {warm['process_wall_s']:.2f}s; median of {warm['n']})"
        )
        print(f"    cache saves {c['saved_s']:.2f}s ({c['speedup']:.0f}x); {c['cache_files_written']} cache files")
    k = res.get("cli")
    if k:
        if k["measured"]:
            print(
                f"{'4 refexmc run nominal (warm)':34s} {k['median_s']:9.2f}s {k['min_s']:9.2f}s {'':>10s}"
                f" {'< ' + format(TARGET_CLI_S, 'g') + 's':>10s}  {_verdict(k['pass'])}"
            )
            print(
                f"    n = {len(k['walls_s'])}; for scale: `--help` {k['help_median_s']:.2f}s, "
                f"bare `python -c pass` {k['python_startup_median_s']:.2f}s"
            )
        else:
            print(f"{'4 refexmc run nominal (warm)':34s} not measured: {k['reason']}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, help="also write all numbers to this JSON file")
    parser.add_argument("--reps", type=int, default=60, help="flight / bare-RK4 repetitions (default 60, >= 30)")
    parser.add_argument("--cli-reps", type=int, default=5, help="timed CLI runs (default 5)")
    parser.add_argument("--warm-reps", type=int, default=3, help="warm-cache compile children (default 3)")
    parser.add_argument("--quick", action="store_true", help="only benchmarks 1 and 2 (in-process)")
    parser.add_argument("--no-pin", action="store_true", help="do not pin the timing loop to one CPU")
    args = parser.parse_args(argv)
    if args.reps < 30:
        parser.error("--reps must be at least 30 (the target is a median over >= 30 runs)")
    os.chdir(ROOT)

    started = time.perf_counter()
    res = {"machine": machine_info(), "command": " ".join([Path(sys.executable).name] + sys.argv)}

    # Pin the in-process loop to one CPU (the target is "on one core"); subprocesses get the
    # original affinity back, like a user's shell.
    affinity = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else None
    cpu = None
    if affinity and not args.no_pin:
        cpu = max(affinity)
        os.sched_setaffinity(0, {cpu})
    try:
        res.update(bench_flight_vs_rk4(args.reps, cpu))
    finally:
        if affinity and cpu is not None:
            os.sched_setaffinity(0, affinity)

    if not args.quick:
        res["compile"] = bench_compile(args.warm_reps)
        res["cli"] = bench_cli(args.cli_reps)
    res["bench_wall_s"] = time.perf_counter() - started

    print_report(res)
    print(f"\n(benchmark wall time {res['bench_wall_s']:.0f} s)")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(res, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
