"""Fly campaigns/spore-failure-sweep.yaml in-process and print the result of docs/spore.md's sweep.

Every single and double undetected thruster failure of spore-sm (12 + 66 = 78 sets) plus the
nominal run 0, undispersed, through the whole deorbit. Each set is also judged from the geometry
alone: can the thrusters left still make a torque of either sense about every body axis
(scipy.optimize.linprog feasibility of H u = ±e_i, u >= 0)? Takes a few seconds after the numba
kernels are compiled (cached on disk).

    .venv/bin/python docs/gen_spore_failure_sweep.py           # print the result
    .venv/bin/python docs/gen_spore_failure_sweep.py --write   # replace it in docs/spore.md

With ``--detected`` it flies campaigns/spore-failure-sweep-detected.yaml too (the same sets, the
flight software told: its LP leaves the failed thrusters out) and makes the comparison of the two
sweeps, between the ``detected-sweep`` markers of docs/spore.md:

    .venv/bin/python docs/gen_spore_failure_sweep.py --detected --write
"""

import math
import sys
from pathlib import Path

import numpy as np
from gen_failure_sweep import (  # noqa: F401 (BEGIN, END: the markers of docs/spore.md too)
    BEGIN,
    END,
    completes,
    failed_set,
    fly_sweep,
    main,
    number,
    provenance,
    write_between_markers,
)
from scipy.optimize import linprog

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "campaigns" / "spore-failure-sweep.yaml"
DETECTED_CAMPAIGN = ROOT / "campaigns" / "spore-failure-sweep-detected.yaml"
DETECTED_BEGIN = "<!-- detected-sweep:begin -->"
DETECTED_END = "<!-- detected-sweep:end -->"
DOC = Path(__file__).with_name("spore.md")
POINTING_LIMIT_DEG = 2.0  # issue 13: the burn completes with the engine within 2 deg of the command
AXES = "xyz"


def lost_torque_senses(vehicle, failed):
    """The body-axis torque senses ("+x", ..., "-z") the thrusters left cannot produce at all.

    A convex cone holds every torque exactly when it holds +-e_x, +-e_y, +-e_z, so an empty list
    means full three-axis authority (at reduced capacity).
    """
    thrusters = [t for t in vehicle["rcs"]["thrusters"] if t["id"] not in failed]
    centre = np.asarray(vehicle["com_offset_m"], dtype=float)
    arms = np.array(
        [
            np.cross(np.asarray(t["position_m"], float) - centre, np.asarray(t["direction"], float))
            / np.linalg.norm(t["direction"])
            for t in thrusters
        ]
    ).T
    lost = []
    for axis in range(3):
        for sign, name in ((1.0, "+"), (-1.0, "-")):
            target = np.zeros(3)
            target[axis] = sign
            result = linprog(np.ones(arms.shape[1]), A_eq=arms, b_eq=target, bounds=(0, None), method="highs")
            if result.status != 0:
                lost.append(f"{name}{AXES[axis]}")
    return lost


def within_limit(row):
    """The deorbit completed and the engine stayed within 2 deg of the command through the burn."""
    return completes(row) and row["burn_pointing_max_deg"] <= POINTING_LIMIT_DEG


def entry_miss_km(row, nominal, radius_m):
    """Great-circle distance between a run's entry point and the nominal run's (haversine)."""
    if not completes(row):
        return math.nan
    lat1, lat2 = math.radians(nominal["entry_latitude_deg"]), math.radians(row["entry_latitude_deg"])
    dlat = lat2 - lat1
    dlon = math.radians(row["entry_longitude_deg"] - nominal["entry_longitude_deg"])
    h = math.sin(dlat / 2) ** 2 + math.cos(lat1) * math.cos(lat2) * math.sin(dlon / 2) ** 2
    return 2.0 * radius_m * math.asin(math.sqrt(h)) / 1000.0


def _entry_radius_m(campaign):
    mission = campaign["mission"]
    return mission["earth"]["radius_m"] + mission["orbit"]["entry_interface_altitude_m"]


def table(campaign, rows):
    """Markdown table, one line per run."""
    vehicle = campaign["vehicle"]
    tank_kg = vehicle["rcs"]["propellant_kg"]
    nominal = rows[0]
    radius_m = _entry_radius_m(campaign)
    lines = [
        "| run | failed thrusters | torque senses lost | completes | failure reason | burn pointing RMS [deg] "
        f"| burn pointing max [deg] | within {POINTING_LIMIT_DEG:g} deg | entry FPA [deg] | entry miss [km] "
        f"| cold gas used [kg] | fits the {tank_kg:g} kg tank |",
        "|---:|---|---|---|---|---:|---:|---|---:|---:|---:|---|",
    ]
    for row in rows:
        failed = failed_set(row)
        done = completes(row)
        cells = (
            str(row["run_id"]),
            f"[{', '.join(map(str, failed))}]" if failed else "none",
            ", ".join(lost_torque_senses(vehicle, failed)) or "none",
            "yes" if done else "no",
            row["failure_reason"] or "—",
            number(row["burn_pointing_rms_deg"], ".3f"),
            number(row["burn_pointing_max_deg"], ".3f"),
            "yes" if within_limit(row) else "**no**",
            number(row["entry_flight_path_angle_deg"], ".5f"),
            number(entry_miss_km(row, nominal, radius_m), ".3f"),
            number(row["fuel_used_kg"], ".3f"),
            ("yes" if row["fuel_used_kg"] <= tank_kg else "**no**") if done else "—",
        )
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _names(group):
    return ", ".join(f"[{', '.join(map(str, s))}]" for s in group) or "none"


def summary(campaign, rows):
    """Which sets complete within the limit, the geometry's verdict, and the worst completing sets."""
    vehicle = campaign["vehicle"]
    nominal = rows[0]
    radius_m = _entry_radius_m(campaign)
    failures = [r for r in rows if r["failed_thrusters"]]
    good = [r for r in failures if within_limit(r)]
    bad = [r for r in failures if not within_limit(r)]
    agree = sum(within_limit(r) == (not lost_torque_senses(vehicle, failed_set(r))) for r in failures)
    lines = [
        f"- Nominal run (no failure): {'completes' if within_limit(nominal) else 'does NOT complete'}, "
        f"burn pointing max {nominal['burn_pointing_max_deg']:.3f} deg.",
    ]
    for size, label in ((1, "single"), (2, "double")):
        of_size = [r for r in failures if len(failed_set(r)) == size]
        ok = [r for r in of_size if within_limit(r)]
        lines.append(
            f"- {label.capitalize()} failures that complete the burn within {POINTING_LIMIT_DEG:g} deg: "
            f"**{len(ok)} of {len(of_size)}**."
        )
    reasons = sorted({r["failure_reason"] or "pointing above the limit" for r in bad})
    lines.append(f"- Sets that do not ({len(bad)}): {_names([failed_set(r) for r in bad])}; {', '.join(reasons)}.")
    lines.append(
        f"- A set completes exactly when its thrusters left still make torque of both senses about every "
        f"axis (linprog on the geometry): **{agree} of {len(failures)}** sets agree."
    )
    if good:
        worst = max(good, key=lambda r: r["burn_pointing_max_deg"])
        far = max(good, key=lambda r: entry_miss_km(r, nominal, radius_m))
        fuel = max(good, key=lambda r: r["fuel_used_kg"])
        lines.append(
            f"- Worst completing sets: pointing max {worst['burn_pointing_max_deg']:.3f} deg "
            f"({_names([failed_set(worst)])}); entry miss {entry_miss_km(far, nominal, radius_m):.3f} km "
            f"({_names([failed_set(far)])}); cold gas {fuel['fuel_used_kg']:.3f} kg ({_names([failed_set(fuel)])})."
        )
    return "\n".join(lines) + "\n"


def generate(campaign_file=CAMPAIGN):
    campaign, rows = fly_sweep(campaign_file)
    script = "docs/gen_spore_failure_sweep.py"
    return f"{provenance(script)}\n\n{summary(campaign, rows)}\n{table(campaign, rows)}"


def _pointing(row):
    return number(row["burn_pointing_max_deg"], ".3f") if completes(row) else "—"


def _outcome(row):
    if within_limit(row):
        return f"within {POINTING_LIMIT_DEG:g} deg"
    return f"**{row['failure_reason'] or 'pointing above the limit'}**"


def _worst(rows):
    """The largest burn pointing max of the rows that complete, and its set."""
    done = [r for r in rows if completes(r)]
    if not done:
        return "—"
    worst = max(done, key=lambda r: r["burn_pointing_max_deg"])
    return f"{worst['burn_pointing_max_deg']:.3f} ({_names([failed_set(worst)])})"


def comparison(campaign, undetected, detected):
    """The undetected and the detected sweep side by side: per set size, then per set."""
    vehicle = campaign["vehicle"]
    by_set = {failed_set(r): r for r in undetected}
    lost = {failed_set(r): lost_torque_senses(vehicle, failed_set(r)) for r in detected}
    failures = [r for r in detected if r["failed_thrusters"]]
    agree = sum(within_limit(r) == (not lost[failed_set(r)]) for r in failures)
    steerable = [r for r in failures if not lost[failed_set(r)]]
    lines = [
        f"- Nominal run (no failure): burn pointing max {detected[0]['burn_pointing_max_deg']:.3f} deg "
        f"(undetected sweep: {undetected[0]['burn_pointing_max_deg']:.3f} deg).",
        f"- Detected: a set completes within {POINTING_LIMIT_DEG:g} deg exactly when its thrusters left still make "
        f"torque of both senses about every axis (linprog on the geometry): **{agree} of {len(failures)}** sets "
        "agree.",
        f"- Detected, the sets the geometry can still steer ({len(steerable)}): burn pointing max at most "
        f"{max(r['burn_pointing_max_deg'] for r in steerable):.3f} deg, against "
        f"{detected[0]['burn_pointing_max_deg']:.3f} deg without a failure.",
        "",
        f"| failed thrusters | sets | undetected: within {POINTING_LIMIT_DEG:g} deg | undetected: worst pointing max "
        f"[deg] | detected: within {POINTING_LIMIT_DEG:g} deg | detected: worst pointing max [deg] |",
        "|---|---:|---:|---|---:|---|",
    ]
    for size, label in ((1, "single"), (2, "double")):
        new = [r for r in failures if len(failed_set(r)) == size]
        old = [by_set[failed_set(r)] for r in new]
        lines.append(
            f"| {label} | {len(new)} | {sum(map(within_limit, old))} | {_worst(old)} "
            f"| {sum(map(within_limit, new))} | {_worst(new)} |"
        )
    lines += [
        "",
        "| run | failed thrusters | torque senses lost | undetected: outcome | undetected: pointing max [deg] "
        "| detected: outcome | detected: pointing max [deg] | detected: cold gas used [kg] |",
        "|---:|---|---|---|---:|---|---:|---:|",
    ]
    for row in detected:
        failed = failed_set(row)
        old = by_set[failed]
        cells = (
            str(row["run_id"]),
            f"[{', '.join(map(str, failed))}]" if failed else "none",
            ", ".join(lost[failed]) or "none",
            _outcome(old),
            _pointing(old),
            _outcome(row),
            _pointing(row),
            number(row["fuel_used_kg"], ".3f"),
        )
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def generate_detected(undetected_file=CAMPAIGN, detected_file=DETECTED_CAMPAIGN):
    """The comparison of docs/spore.md's detected-sweep section, both sweeps flown in this process."""
    _, undetected = fly_sweep(undetected_file)
    campaign, detected = fly_sweep(detected_file)
    script = "docs/gen_spore_failure_sweep.py --detected"
    return f"{provenance(script)}\n\n{comparison(campaign, undetected, detected)}"


def write_detected(generated, doc=DOC):
    """Replace the text between the detected-sweep markers of ``doc`` with ``generated``."""
    head, rest = doc.read_text().split(DETECTED_BEGIN, 1)
    _, tail = rest.split(DETECTED_END, 1)
    doc.write_text(f"{head}{DETECTED_BEGIN}\n{generated}{DETECTED_END}{tail}")


if __name__ == "__main__":
    if "--detected" in sys.argv[1:]:
        text = generate_detected()
        if "--write" in sys.argv[1:]:
            write_detected(text)
        else:
            sys.stdout.write(text)
    else:
        main(sys.argv[1:], generate, DOC)
