"""SPORE against 004 Table 2: one campaign per reading of 004's text, flown, and the 3-sigma table.

004 gives Table 1's errors (ADCS pointing 1 deg, GPS position 1.8 m, GPS velocity 0.03 m/s, 3 sigma)
without saying whether each is a bias per run or a noise per step, whether the pointing error sits
in the attitude knowledge or in the actuation, or which gains its PD burn guidance has (its
equation is missing from the text). Each reading below is campaigns/spore-deorbit-iss.yaml with
one of those choices changed; the rest (inertia, centre of mass, thrust scale, initial state, sensor
noise) is the base campaign's.

    .venv/bin/python docs/gen_spore_readings.py --campaigns        # (re)write campaigns/spore-readings/
    .venv/bin/python docs/gen_spore_readings.py [--runs-dir DIR] [-j 2] [--write]

The second flies every reading that DIR (default /tmp/spore-readings) does not hold yet with
``refexmc run campaigns/spore-readings/NAME.yaml -o DIR/NAME -j J`` and prints the table of the
five entry quantities' 3 sigma beside 004 Table 2 (ISS); ``--write`` puts it in docs/spore.md.
"""

import copy
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import yaml
from gen_failure_sweep import provenance

ROOT = Path(__file__).resolve().parents[1]
BASE = ROOT / "campaigns" / "spore-deorbit-iss.yaml"
FOLDER = ROOT / "campaigns" / "spore-readings"
DOC = Path(__file__).with_name("spore.md")
BEGIN = "<!-- readings:begin -->"
END = "<!-- readings:end -->"
RUNS = 500  # 3-sigma to ~3 % (1 / sqrt(2 n)); the base campaign flies 1000
QUANTITIES = [  # runs column, label, format
    ("entry_longitude_deg", "longitude", ".4g"),
    ("entry_latitude_deg", "latitude", ".4g"),
    ("entry_flight_path_angle_deg", "FPA", ".3g"),
    ("entry_heading_deg", "heading", ".3g"),
    ("entry_speed_m_s", "speed", ".3g"),
]

# Table 1's 1 deg ADCS pointing error (3 sigma) from one source alone: 0.29 deg 1 sigma about each
# axis across the engine gives a 2D angle whose 99.73 % quantile is 0.29 * sqrt(-2 ln 0.0027) = 1.0 deg.
POINTING_SIGMA_DEG = 0.29
GPS_POSITION_SIGMA_M = 0.6  # 004 Table 1: 1.8 m 3 sigma, per axis
GPS_VELOCITY_SIGMA_M_S = 0.01  # 004 Table 1: 0.03 m/s 3 sigma, per axis
ZERO3 = {"dist": "constant", "value": [0.0, 0.0, 0.0]}


def _normal3(sigma, z=True):
    return {"dist": "normal", "mean": [0, 0, 0], "sigma": [sigma, sigma, sigma if z else 0.0]}


# name -> (what it reads 004 as, dispersion changes, burn_guidance changes, deorbit plan changes)
READINGS = {
    "gps-noise": (
        "GPS errors as white noise per guidance step (1 Hz), no bias",
        {
            "navigation.gps_position_bias_m": None,
            "navigation.gps_velocity_bias_m_s": None,
            "navigation.gps_position_noise_m": {"dist": "constant", "value": GPS_POSITION_SIGMA_M},
            "navigation.gps_velocity_noise_m_s": {"dist": "constant", "value": GPS_VELOCITY_SIGMA_M_S},
        },
        {},
        {},
    ),
    "no-table-1": (
        "none of Table 1's errors: only the base's other dispersions (centre of mass, inertia, RCS, initial state, "
        "sensor noise)",
        {
            "navigation.gps_position_bias_m": None,
            "navigation.gps_velocity_bias_m_s": None,
            "navigation.attitude_bias_deg": None,
            "main_engine.misalignment_deg": None,
        },
        {},
        {},
    ),
    "gps-only": (
        "Table 1's GPS biases without its pointing sources (no attitude bias, no misalignment)",
        {"navigation.attitude_bias_deg": None, "main_engine.misalignment_deg": None},
        {},
        {},
    ),
    "pointing-only": (
        "the base campaign's pointing errors alone: no GPS error",
        {"navigation.gps_position_bias_m": None, "navigation.gps_velocity_bias_m_s": None},
        {},
        {},
    ),
    "pointing-knowledge": (
        "the 1 deg pointing all in the attitude knowledge (a bias per run)",
        {
            "navigation.attitude_bias_deg": _normal3(POINTING_SIGMA_DEG),
            "main_engine.misalignment_deg": None,
        },
        {},
        {},
    ),
    "pointing-actuation": (
        "the 1 deg pointing all in the actuation (engine misalignment per run)",
        {
            "navigation.attitude_bias_deg": None,
            "main_engine.misalignment_deg": _normal3(POINTING_SIGMA_DEG, z=False),
        },
        {},
        {},
    ),
    "pointing-noise": (
        "the 1 deg pointing as attitude-knowledge white noise per control step (10 Hz), no bias",
        {
            "navigation.attitude_bias_deg": None,
            "main_engine.misalignment_deg": None,
            "navigation.attitude_noise_deg": {"dist": "constant", "value": POINTING_SIGMA_DEG},
        },
        {},
        {},
    ),
    "pd-velocity": (
        "PD guidance weighted toward velocity: k_r = 0, k_v = 0.06 1/s",
        {},
        {"position_gain_s2": 0.0, "velocity_gain_s": 0.06},
        {},
    ),
    "pd-velocity-weak": (
        "PD guidance on velocity alone, ten times weaker: k_r = 0, k_v = 0.006 1/s (a 170 s time constant)",
        {},
        {"position_gain_s2": 0.0, "velocity_gain_s": 0.006},
        {},
    ),
    "pd-position": (
        "PD guidance weighted toward position: k_r = 1e-3 1/s^2, k_v = 0.006 1/s (zeta 0.1)",
        {},
        {"position_gain_s2": 0.001, "velocity_gain_s": 0.006},
        {},
    ),
    "open-loop-hohmann": (
        "open loop, Hohmann direction (the plan's fixed inertial direction), the plan's burn time",
        {},
        {"law": "open_loop_planned"},
        {},
    ),
    "open-loop-retrograde": (
        "open loop, thrust along -v_gps, the burn time of the opposite_velocity plan",
        {},
        {"law": "open_loop_retrograde"},
        {"approach": "opposite_velocity"},
    ),
}


def _relative(path):
    return str(Path("..") / ".." / path.relative_to(ROOT))


def campaign_text(name):
    """The campaign file of reading ``name``: the base campaign with the reading's changes."""
    what, dispersion_changes, guidance_changes, plan_changes = READINGS[name]
    base = yaml.safe_load(BASE.read_text())
    campaign = copy.deepcopy(base)
    campaign["name"] = f"spore-reading-{name}"
    campaign["runs"] = RUNS
    header = [
        f"# 004 Table 2 by experiment (docs/spore.md): {what}.",
        "# Generated by docs/gen_spore_readings.py --campaigns from campaigns/spore-deorbit-iss.yaml; edit the",
        "# script, not this file.",
    ]
    vehicle_file = (BASE.parent / base["vehicle"]).resolve()
    mission_file = (BASE.parent / base["mission"]).resolve()
    campaign["vehicle"] = _relative(vehicle_file)
    campaign["mission"] = _relative(mission_file)
    if guidance_changes:
        vehicle = yaml.safe_load(vehicle_file.read_text())
        vehicle["flight_software"]["burn_guidance"].update(guidance_changes)
        campaign["vehicle"] = vehicle
        header.append(f"# vehicle: configs/vehicles/spore-sm.yaml inline, burn_guidance {guidance_changes}")
    if plan_changes:
        mission = yaml.safe_load(mission_file.read_text())
        mission["orbit"]["deorbit"].update(plan_changes)
        campaign["mission"] = mission
        header.append(f"# mission: configs/missions/spore-deorbit-iss.yaml inline, orbit.deorbit {plan_changes}")
    dispersions = campaign["dispersions"]
    for path, spec in dispersion_changes.items():
        if spec is None:
            dispersions.pop(path, None)
        else:
            dispersions[path] = spec
    body = yaml.safe_dump(campaign, sort_keys=False, default_flow_style=None, width=110)
    return "\n".join(header) + "\n" + body


def write_campaigns():
    FOLDER.mkdir(exist_ok=True)
    for name in READINGS:
        (FOLDER / f"{name}.yaml").write_text(campaign_text(name))


def campaign_files():
    """(name, file) of every row: the base campaign first, then each reading."""
    return [("base", BASE)] + [(name, FOLDER / f"{name}.yaml") for name in READINGS]


def fly(runs_dir, jobs):
    """Fly every campaign whose runs ``runs_dir`` lacks; return {name: runs DataFrame}."""
    out = {}
    refexmc = Path(sys.executable).with_name("refexmc")
    for name, file in campaign_files():
        target = runs_dir / name
        if not (target / "runs").is_dir():
            subprocess.run([str(refexmc), "run", str(file), "-o", str(target), "-j", str(jobs)], check=True)
        out[name] = pd.read_parquet(target / "runs")
    return out


def published():
    values = yaml.safe_load(BASE.read_text())["published"][0]["values"]
    return [values[column] for column, _, _ in QUANTITIES]


def _ok(runs):
    return runs[(runs["status"] == "ok") & runs["success"].astype(bool)]


def three_sigma(runs):
    ok = _ok(runs)
    return [3.0 * ok[column].std(ddof=1) for column, _, _ in QUANTITIES], len(ok), len(runs)


def heading_off_track(runs):
    """3 sigma of the heading left after a straight-line fit on the latitude: along one ground
    track the heading is a function of the latitude, so this is the part that is not."""
    ok = _ok(runs)
    lat, heading = ok["entry_latitude_deg"].to_numpy(), ok["entry_heading_deg"].to_numpy()
    slope, intercept = np.polyfit(lat - lat.mean(), heading, 1)
    return 3.0 * (heading - slope * (lat - lat.mean()) - intercept).std(ddof=2), slope


def table(flown):
    ref = published()
    head = "| reading | runs ok | " + " | ".join(f"{label} 3σ (004 / this)" for _, label, _ in QUANTITIES)
    lines = [
        head + " | heading / latitude 3σ | d heading / d latitude | heading off the track 3σ"
        " | burn pointing RMS, mean [deg] |",
        "|---|---:|" + "---:|" * len(QUANTITIES) + "---:|---:|---:|---:|",
    ]
    ref_cells = " | ".join(format(v, fmt) for v, (_, _, fmt) in zip(ref, QUANTITIES, strict=True))
    lines.append(f"| 004 Table 2 ISS | 1000 | {ref_cells} | {ref[3] / ref[1]:.3g} | | | ~1 (3σ, Table 1) |")
    for name, runs in flown.items():
        sigmas, n_ok, n = three_sigma(runs)
        cells = []
        for value, published_value, (_, _, fmt) in zip(sigmas, ref, QUANTITIES, strict=True):
            ratio = published_value / value if value > 0 else math.inf
            cells.append(f"{format(value, fmt)} ({ratio:.3g})")
        off_track, slope = heading_off_track(runs)
        pointing = _ok(runs)["burn_pointing_rms_deg"].mean()
        lines.append(
            f"| `{name}` | {n_ok}/{n} | "
            + " | ".join(cells)
            + f" | {sigmas[3] / sigmas[1]:.3g} | {slope:.3g} | {off_track:.3g} | {pointing:.2f} |"
        )
    lines.append("")
    lines.append("Readings (each `campaigns/spore-readings/NAME.yaml`; `base` is `campaigns/spore-deorbit-iss.yaml`):")
    lines.append("")
    lines.append("- `base`: GPS biases per run, pointing from an attitude bias and an engine misalignment, PD guidance")
    for name, (what, *_rest) in READINGS.items():
        lines.append(f"- `{name}`: {what}")
    return "\n".join(lines) + "\n"


def main(argv):
    if "--campaigns" in argv:
        write_campaigns()
        return
    runs_dir = Path(argv[argv.index("--runs-dir") + 1]) if "--runs-dir" in argv else Path("/tmp/spore-readings")
    jobs = int(argv[argv.index("-j") + 1]) if "-j" in argv else 2
    generated = f"{provenance('docs/gen_spore_readings.py')}\n\n{table(fly(runs_dir, jobs))}"
    if "--write" in argv:
        head, rest = DOC.read_text().split(BEGIN, 1)
        _, tail = rest.split(END, 1)
        DOC.write_text(f"{head}{BEGIN}\n{generated}{END}{tail}")
    else:
        sys.stdout.write(generated)


if __name__ == "__main__":
    main(sys.argv[1:])
