"""Bad input, one test per class: one clear message, exit 2, no traceback, nothing written or lost.

Every case runs `refexmc run ... -o OUT --overwrite` against an OUT that already holds a
finished campaign's files: bad input must neither create an output directory nor touch one.
"""

import subprocess
import sys
from pathlib import Path

import pytest
from click.testing import CliRunner

from refexmc.cli import main

ROOT = Path(__file__).resolve().parents[1]
SMOKE = (ROOT / "campaigns/smoke.yaml").read_text().replace("../configs/", f"{ROOT}/configs/")
INLINE_VEHICLE = (ROOT / "configs/vehicles/refex.yaml").read_text()


def _edit(old, new, count=1):
    assert old in SMOKE, old
    return SMOKE.replace(old, new, count)


def _line(prefix):
    return next(n for n, line in enumerate(SMOKE.splitlines(), 1) if line.startswith(prefix))


def _inline_vehicle(inertia_rows):
    body = INLINE_VEHICLE
    start = body.index("inertia_kg_m2:")
    end = body.index("com_offset_m:")
    body = body[:start] + "inertia_kg_m2: " + inertia_rows + "\n" + body[end:]
    indented = "\n".join("  " + line for line in body.splitlines())
    return _edit(f"vehicle: {ROOT}/configs/vehicles/refex.yaml", "vehicle:\n" + indented)


# (case id, campaign text or None for a missing file, extra CLI args, words the message must contain)
CASES = [
    ("missing-file", None, [], ["file not found"]),
    # an unclosed flow sequence: the parser stops at the next line's ':'
    ("yaml-syntax", _edit("runs: 20", "runs: [20"), [], ["YAML syntax error", f":{_line('seed:')}:"]),
    (
        "unknown-key",
        _edit("sampling: lhs", "sampleing: lhs"),
        [],
        ["unknown key 'sampleing'", "did you mean 'sampling'"],
    ),
    (
        "unknown-path",
        _edit("initial_state.rates_deg_s:", "initial_state.rate_deg_s:"),
        [],
        ["dispersions.initial_state.rate_deg_s", "did you mean 'initial_state.rates_deg_s'"],
    ),
    ("wrong-type", _edit("runs: 20", "runs: twenty"), [], ["runs", "expected integer", "'twenty'"]),
    (
        "negative-sigma",
        _edit("sigma: [1.0, 1.0, 1.0]", "sigma: [1.0, -1.0, 1.0]"),
        [],
        ["dispersions.initial_state.rates_deg_s.sigma", "expected sigma >= 0"],
    ),
    ("runs-zero", _edit("runs: 20", "runs: 0"), [], ["runs", "expected a value >= 1"]),
    ("runs-option-zero", SMOKE, ["--runs", "0"], ["--runs", "expected runs >= 1"]),
    (
        "thruster-9",
        _edit("failures:\n  mode: none", "failures:\n  mode: fixed\n  thrusters: [1, 9]"),
        [],
        ["failures.thrusters.1", "thruster id 1..8, got 9"],
    ),
    (
        "detected-not-boolean",
        _edit("failures:\n  mode: none", "failures:\n  mode: fixed\n  thrusters: [1]\n  detected: maybe"),
        [],
        ["failures.detected", "expected boolean", "'maybe'"],
    ),
    (
        "detected-without-failures",
        _edit("failures:\n  mode: none", "failures:\n  mode: none\n  detected: true"),
        [],
        ["failures.detected", "'detected' is not used with mode none"],
    ),
    ("seed-not-integer", _edit("seed: 20231121", "seed: 1.5"), [], ["seed", "expected integer", "1.5"]),
    ("seed-option-not-integer", SMOKE, ["--seed", "abc"], ["--seed", "abc"]),
    (
        "non-physical-inertia",
        _inline_vehicle("[[20, 0, 0], [0, 100, 0], [0, 0, 250]]"),
        [],
        ["vehicle.inertia_kg_m2", "triangle inequality"],
    ),
    (
        "unknown-distribution",
        _edit("{dist: lognormal, median: 1.0, sigma: 0.1}", "{dist: log_normal, median: 1.0, sigma: 0.1}"),
        [],
        ["dispersions.atmosphere.density_scale.dist", "unknown distribution 'log_normal'", "did you mean 'lognormal'"],
    ),
    (
        "unknown-requirement-metric",
        _edit("  - fuel_remaining.min >= 0.20", "  - fuel_remainig.min >= 0.20"),
        [],
        [
            f":{_line('  - fuel_remaining.min')}:",
            "requirements.0",
            "unknown metric 'fuel_remainig.min'",
            "did you mean 'fuel_remaining.min'",
        ],
    ),
    (
        "unknown-requirement-statistic",
        _edit("  - success_rate >= 1.0", "  - p.atmosphere.density_scale.mediane <= 1.1"),
        [],
        ["requirements.1", "unknown statistic 'mediane'", "did you mean 'p.atmosphere.density_scale.median'"],
    ),
    (
        "isp-uniform-to-inf",
        _edit("dispersions:\n", "dispersions:\n  rcs.isp_s: {dist: uniform, low: 60, high: .inf}\n"),
        [],
        [f":{_line('dispersions:') + 1}:", "dispersions.rcs.isp_s.high", "expected a finite number, got .inf"],
    ),
    (
        "nan-in-a-vector",
        _edit("sigma: [1.0, 1.0, 1.0]", "sigma: [1.0, .NaN, 1.0]"),
        [],
        ["dispersions.initial_state.rates_deg_s.sigma.1", "expected a finite number, got .NaN"],
    ),
    (
        "overflowing-number",
        _edit("history_rate_hz: 2", "history_rate_hz: 1e999"),
        [],
        ["output.history_rate_hz", "expected a finite number, got 1e999, which overflows a float"],
    ),
    (
        "duplicate-top-level-key",
        _edit("seed: 20231121", "seed: 20231121\nseed: 7"),
        [],
        [f":{_line('seed:') + 1}:", "seed: duplicate key 'seed'", f"first at line {_line('seed:')}"],
    ),
    (
        "duplicate-dispersion-path",
        _edit("dispersions:\n", "dispersions:\n  com_offset_m: {dist: normal, sigma: 0.1}\n"),
        [],
        ["dispersions.com_offset_m: duplicate key 'com_offset_m'", f"first at line {_line('dispersions:') + 1}"],
    ),
    (
        "published-column-the-campaign-lacks",
        SMOKE
        + "published:\n  - source: 004 Table 2\n    statistic: three_sigma\n    values: {entry_speed_m_s: 0.04}\n",
        [],
        [
            f":{len(SMOKE.splitlines()) + 4}:",
            "published.0.values.entry_speed_m_s",
            "not a runs column of this campaign",
            "orbit trajectory only",
        ],
    ),
    (
        "published-unknown-statistic",
        SMOKE + "published:\n  - source: 000 sec. 6.2\n    statistic: sigma3\n    values: {fuel_remaining: 0.1}\n",
        [],
        [f":{len(SMOKE.splitlines()) + 3}:", "published.0.statistic", "unknown statistic 'sigma3'"],
    ),
    ("runs-option-inf", SMOKE, ["--runs", "inf"], ["--runs", "'inf' is not a valid integer"]),
    ("seed-option-nan", SMOKE, ["--seed", "nan"], ["--seed", "'nan' is not a valid integer"]),
    (
        "unbounded-normal-on-positive-quantity",
        _edit("{dist: truncnorm, sigma: 2.25, low: 0.0}", "{dist: normal, sigma: 60.0}"),
        [],
        ["rcs.valve_time_constants_ms.high.fall", "outside the physical range >= 0"],
    ),
]


def _pointing(**fields):
    """SMOKE with a pointing requirement (issue 35, docs/pointing.md) after its own; ``fields``
    replace the defaults; the value None drops a field."""
    record = {
        "index": "APE",
        "error": "total",
        "bound_deg": "0.5",
        "p_c": "0.9973",
        "interpretation": "temporal",
        "window": "{modes: [GEEM]}",
    }
    record.update(fields)
    items = [f"{key}: {value}" for key, value in record.items() if value is not None]
    return SMOKE + "  - " + "\n    ".join(items) + "\n"


def _pointing_line(key):
    """The line of ``key`` in :func:`_pointing`'s text (the record starts after SMOKE's last line)."""
    keys = ["index", "error", "bound_deg", "p_c", "interpretation", "window"]
    return len(SMOKE.splitlines()) + 1 + keys.index(key)


_NO_ATTITUDE_KNOWLEDGE = "  navigation.attitude_bias_deg: {dist: normal, mean: [0, 0, 0], sigma: [0.5, 0.5, 0.5]}\n"
CASES += [
    (
        "pointing-unknown-index",
        _pointing(index="APX"),
        [],
        [f":{_pointing_line('index')}:", "requirements.2.index", "expected one of APE, MPE, RPE, PDE, PRE"],
    ),
    (
        "pointing-unknown-interpretation",
        _pointing(interpretation="worst"),
        [],
        [f":{_pointing_line('interpretation')}:", "requirements.2.interpretation", "temporal, ensemble, mixed"],
    ),
    (
        "pointing-p-c-one",
        _pointing(p_c="1.0"),
        [],
        [f":{_pointing_line('p_c')}:", "requirements.2.p_c", "expected a value < 1.0, got 1.0"],
    ),
    (
        "pointing-p-c-zero",
        _pointing(p_c="0"),
        [],
        [f":{_pointing_line('p_c')}:", "requirements.2.p_c", "expected a value > 0.0, got 0"],
    ),
    (
        "pointing-window-names-no-mode",
        _pointing(window="{modes: [science]}"),
        [],
        [f":{_pointing_line('window')}:", "requirements.2.window.modes.0", "no mode 'science' in the mission"],
    ),
    (
        "pointing-knowledge-without-navigation",
        _pointing(index="AKE").replace(_NO_ATTITUDE_KNOWLEDGE, ""),
        [],
        [f":{_pointing_line('index') - 1}:", "requirements.2.index", "AKE is a knowledge index"],
    ),
]


@pytest.fixture
def existing_out(tmp_path):
    out = tmp_path / "out"
    (out / "runs").mkdir(parents=True)
    (out / "runs" / "part-00000.parquet").write_bytes(b"results of an earlier campaign")
    (out / "manifest.json").write_text("{}")
    return out


def _snapshot(out):
    return {p.relative_to(out): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


@pytest.mark.parametrize(("text", "args", "words"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_bad_campaign_is_refused_with_one_message(tmp_path, existing_out, text, args, words):
    campaign = tmp_path / "campaign.yaml"
    if text is not None:
        campaign.write_text(text)
    before = _snapshot(existing_out)
    fresh = tmp_path / "fresh"
    for out, flags in ((fresh, []), (existing_out, ["--overwrite"])):
        result = CliRunner().invoke(main, ["run", str(campaign), "-o", str(out), "--no-progress", *flags, *args])
        assert result.exit_code == 2, result.output
        assert "Traceback" not in result.output
        assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
        message = result.output.strip()
        for word in words:
            assert word in message, (word, message)
        if text is not None and "option" not in message.lower() and not args:
            assert str(campaign) in message  # names the file
    assert not fresh.exists()
    assert _snapshot(existing_out) == before


def test_existing_out_without_a_flag_is_refused_and_untouched(tmp_path, existing_out):
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(SMOKE)
    before = _snapshot(existing_out)
    result = CliRunner().invoke(main, ["run", str(campaign), "-o", str(existing_out), "--no-progress"])
    assert result.exit_code == 2
    assert "exists" in result.output and "--resume" in result.output and "--overwrite" in result.output
    assert "Traceback" not in result.output
    assert _snapshot(existing_out) == before


@pytest.mark.parametrize(("text", "words"), [(c[1], c[3]) for c in CASES if c[1] is not None and not c[2]])
def test_validate_reports_the_same_problems(tmp_path, text, words):
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(campaign)])
    assert result.exit_code == 2
    assert all(word in result.output for word in words), result.output


# --- the same through a real process: what a user at a shell sees ---------------------------------

REFEXMC = Path(sys.executable).with_name("refexmc")
COMMAND = [str(REFEXMC)] if REFEXMC.exists() else [sys.executable, "-m", "refexmc.cli"]
VEHICLE_TEXT = (ROOT / "configs/vehicles/refex.yaml").read_text()
MISSION_TEXT = (ROOT / "configs/missions/refex-exo.yaml").read_text()

# (case id, file name, text, words the one line on stderr must contain)
PROCESS_CASES = [
    (
        "campaign-isp-to-inf",
        "campaign.yaml",
        dict((c[0], c[1]) for c in CASES)["isp-uniform-to-inf"],
        ["dispersions.rcs.isp_s.high", "expected a finite number, got .inf"],
    ),
    (
        "campaign-duplicate-key",
        "campaign.yaml",
        dict((c[0], c[1]) for c in CASES)["duplicate-top-level-key"],
        ["seed: duplicate key 'seed'"],
    ),
    (
        "vehicle-duplicate-nested-key",
        "vehicle.yaml",
        VEHICLE_TEXT.replace("  isp_s: 70.0", "  isp_s: 70.0\n  isp_s: -.Inf"),
        ["rcs.isp_s: duplicate key 'isp_s'"],
    ),
    (
        "mission-nan",
        "mission.yaml",
        MISSION_TEXT.replace("altitude_m: 85000.0", "altitude_m: .nan", 1),
        ["initial_state.altitude_m: expected a finite number, got .nan"],
    ),
]


def _one_error_line(proc, words, path):
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr + proc.stdout
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr  # one message, no warnings
    assert lines[0].startswith(f"error: {path}:")  # file and line first
    for word in words:
        assert word in lines[0], (word, lines[0])


@pytest.mark.parametrize(("name", "text", "words"), [c[1:] for c in PROCESS_CASES], ids=[c[0] for c in PROCESS_CASES])
def test_refexmc_validate_process_refuses_bad_files(tmp_path, name, text, words):
    path = tmp_path / name
    path.write_text(text)
    proc = subprocess.run([*COMMAND, "validate", str(path)], capture_output=True, text=True, timeout=120)
    _one_error_line(proc, words, path)
    assert proc.stdout == ""


@pytest.mark.parametrize(
    ("text", "words"), [c[2:] for c in PROCESS_CASES if c[1] == "campaign.yaml"], ids=["isp-to-inf", "duplicate-key"]
)
def test_refexmc_run_process_writes_nothing_and_loses_nothing(tmp_path, existing_out, text, words):
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(text)
    before = _snapshot(existing_out)
    fresh = tmp_path / "fresh"
    for out, flags in ((fresh, []), (existing_out, ["--overwrite"])):
        cmd = [*COMMAND, "run", str(campaign), "-o", str(out), "--no-progress", *flags]
        _one_error_line(subprocess.run(cmd, capture_output=True, text=True, timeout=120), words, campaign)
    assert not fresh.exists()
    assert _snapshot(existing_out) == before


def test_refexmc_run_process_refuses_non_finite_options(tmp_path):
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(SMOKE)
    for option, value in (("--runs", "inf"), ("--seed", "nan")):
        out = tmp_path / "out"
        proc = subprocess.run(
            [*COMMAND, "run", str(campaign), "-o", str(out), option, value], capture_output=True, text=True, timeout=120
        )
        assert proc.returncode == 2 and "Traceback" not in proc.stderr
        assert f"Invalid value for '{option}': '{value}' is not a valid integer" in proc.stderr
        assert not out.exists()


# --- bad mode programs: the mission file's own line and key path ---------------------------------


def _mission_edit(old, new):
    assert old in MISSION_TEXT, old
    return MISSION_TEXT.replace(old, new, 1)


def _mission_line(text, fragment):
    return next(n for n, line in enumerate(text.splitlines(), 1) if fragment in line)


_SAM_TARGET = "    target: {type: sun_horizontal}\n    thrust: low\n    exit: [{angle_error_below_deg"
_AFTER_MODES = MISSION_TEXT[MISSION_TEXT.index("attitude_error_end_max") :]
_EMPTY = MISSION_TEXT[: MISSION_TEXT.index("modes:\n")] + "modes: []\n" + _AFTER_MODES
# (case id, mission text, words the message must contain, fragment of the line it must name)
MISSION_CASES = [
    (
        "unknown-kind",
        _mission_edit("kind: spin_up", "kind: spin"),
        ["modes.3.kind", "expected one of locked"],
        "kind: spin",
    ),
    (
        "unknown-predicate",
        _mission_edit("{time_in_mode_s: 8.0}", "{time_in_mode: 8.0}"),
        ["modes.4.exit.0.time_in_mode", "unknown key 'time_in_mode'", "did you mean 'time_in_mode_s'"],
        "time_in_mode: 8.0",
    ),
    (
        "target-the-kind-cannot-use",
        _mission_edit(_SAM_TARGET, _SAM_TARGET.replace("sun_horizontal", "previous")),
        ["modes.2.target.type", "kind slew cannot use target previous"],
        "type: previous",
    ),
    (
        "target-on-a-kind-without-one",
        _mission_edit(
            "    kind: locked\n", "    kind: locked\n    target: {type: inertial, quaternion: [0, 0, 0, 1]}\n"
        ),
        ["modes.0.target", "kind locked takes no target"],
        "type: inertial",
    ),
    (
        "unknown-target-key",
        _mission_edit("bank_deg: 0.0, predicted_at_altitude_m", "bank_deg: 0.0, predicted_altitude_m"),
        ["modes.5.target.predicted_altitude_m", "unknown key", "did you mean 'predicted_at_altitude_m'"],
        "predicted_altitude_m",
    ),
    (
        "predicate-the-kind-cannot-answer",
        _mission_edit("exit: [{time_in_mode_s: 5.0}]", "exit: [{guidance_finished: true}]"),
        [
            "modes.0.exit.0.guidance_finished",
            "needs a profile (rate_damping, slew, spin_up, burn)",
            "kind locked has none",
        ],
        "guidance_finished: true}]",
    ),
    ("empty-mode-list", _EMPTY, ["modes", "expected 1..32 items, got 0"], "modes: []"),
    (
        "duplicate-mode-name",
        _mission_edit("  - name: RDM2", "  - name: rdm1"),
        ["modes.4.name", "mode name 'rdm1' is used twice (also mode 2)"],
        "name: rdm1",
    ),
]


@pytest.mark.parametrize(
    ("text", "words", "fragment"), [c[1:] for c in MISSION_CASES], ids=[c[0] for c in MISSION_CASES]
)
def test_bad_mode_program_is_refused_with_file_line_and_key_path(tmp_path, text, words, fragment):
    path = tmp_path / "mission.yaml"
    path.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert f"{path}:{_mission_line(text, fragment)}:" in result.output, result.output
    for word in words:
        assert word in result.output, (word, result.output)


def test_allocation_naming_a_missing_thruster_is_refused(tmp_path):
    path = tmp_path / "vehicle.yaml"
    text = VEHICLE_TEXT.replace('"+z": [6]', '"+z": [9]')
    path.write_text(text)
    result = CliRunner().invoke(main, ["validate", str(path)])
    assert result.exit_code == 2
    line = next(n for n, s in enumerate(text.splitlines(), 1) if '"+z": [9]' in s)
    assert f"{path}:{line}:" in result.output
    assert "flight_software.allocation.+z.0" in result.output and "expected a thruster id 1..8, got 9" in result.output


def test_a_mission_the_vehicle_cannot_fly_is_refused_in_the_mission_file(tmp_path):
    """generic-12 has no trajectory: a mode that ends on altitude is refused at its line."""
    mission = (ROOT / "configs/missions/generic-slew.yaml").read_text()
    bad = mission.replace("exit: [{time_in_mode_s: 60.0}]", "exit: [{altitude_below_m: 1000.0}]")
    (tmp_path / "mission.yaml").write_text(bad)
    campaign = (ROOT / "campaigns/generic-slew.yaml").read_text()
    campaign = campaign.replace("../configs/missions/generic-slew.yaml", str(tmp_path / "mission.yaml"))
    campaign = campaign.replace("../configs/", f"{ROOT}/configs/")
    (tmp_path / "campaign.yaml").write_text(campaign)
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "campaign.yaml")])
    assert result.exit_code == 2
    line = next(n for n, s in enumerate(bad.splitlines(), 1) if "altitude_below_m: 1000.0" in s)
    assert f"{tmp_path / 'mission.yaml'}:{line}:" in result.output, result.output
    assert "predicate altitude_below_m needs a trajectory; the vehicle has none" in result.output


@pytest.mark.parametrize(
    ("path", "words"),
    [
        ("initial_state.altitude_m", "'initial_state.altitude_m': the mission file does not declare it"),
        ("aerodynamics.mistrim_cm", "acts through the trajectory; vehicle generic-12 has none"),
        ("atmosphere.density_scale", "needs an atmosphere; the mission has none"),
    ],
)
def test_dispersing_what_the_vehicle_or_mission_does_not_have_is_refused(tmp_path, path, words):
    """generic-slew has no trajectory, no aerodynamics and no atmosphere: nothing there to disperse."""
    campaign = (ROOT / "campaigns/generic-slew.yaml").read_text().replace("../configs/", f"{ROOT}/configs/")
    campaign = campaign.replace("dispersions:\n", f"dispersions:\n  {path}: {{dist: normal, sigma: 0.1}}\n", 1)
    (tmp_path / "campaign.yaml").write_text(campaign)
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "campaign.yaml")])
    assert result.exit_code == 2
    line = next(n for n, s in enumerate(campaign.splitlines(), 1) if s.startswith(f"  {path}:"))
    assert f":{line}: dispersions.{path}: " in result.output and words in result.output, result.output


@pytest.mark.parametrize(
    ("campaign", "mission", "old", "new", "words"),
    [
        (
            "generic-slew.yaml",
            "generic-slew.yaml",
            "navigation:\n",
            "navigation:\n  local_position_noise_m: 0.01\n",
            "navigation.local_position_noise_m needs a vehicle with the local trajectory",
        ),
        (
            "surveyor-hop.yaml",
            "surveyor-hop.yaml",
            "tank_pressure_noise_pa: 0.0",
            "tank_pressure_noise_pa: -1.0e4",
            "navigation.tank_pressure_noise_pa",
        ),
    ],
)
def test_bad_local_navigation_noise_is_refused_at_its_line(tmp_path, campaign, mission, old, new, words):
    """A local-trajectory noise on a vehicle without one, or a negative sigma: exit 2, file:line."""
    text = (ROOT / "configs/missions" / mission).read_text()
    assert text.count(old) == 1
    bad = text.replace(old, new)
    (tmp_path / "mission.yaml").write_text(bad)
    source = (ROOT / "campaigns" / campaign).read_text()
    source = source.replace(f"../configs/missions/{mission}", str(tmp_path / "mission.yaml"))
    (tmp_path / "campaign.yaml").write_text(source.replace("../configs/", f"{ROOT}/configs/"))
    result = CliRunner().invoke(main, ["validate", str(tmp_path / "campaign.yaml")])
    assert result.exit_code == 2, result.output
    key = new.strip().splitlines()[-1].split(":")[0].strip()
    line = next(n for n, s in enumerate(bad.splitlines(), 1) if s.strip().startswith(key + ":"))
    assert f"{tmp_path / 'mission.yaml'}:{line}:" in result.output, result.output
    assert words in result.output
    assert "Traceback" not in result.output


# --- plausibility (issue 34): a value in another unit, refused with --strict at the user's key ------

SURVEYOR_TEXT = (ROOT / "configs/vehicles/cold-gas-surveyor.yaml").read_text()
HOP_MISSION = ROOT / "configs/missions/surveyor-hop.yaml"


def _hop_variant(tmp_path, old=None, new=None, dispersions="", vehicle="vehicle.yaml"):
    """A new user's hop: the shipped surveyor with one value changed, the shipped hop mission."""
    assert old is None or SURVEYOR_TEXT.count(old) == 1
    (tmp_path / "vehicle.yaml").write_text(SURVEYOR_TEXT if old is None else SURVEYOR_TEXT.replace(old, new))
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(
        f"name: my-hop\nvehicle: {vehicle}\nmission: {HOP_MISSION}\nruns: 5\nseed: 1\n"
        + (f"dispersions:\n  {dispersions}\n" if dispersions else "")
    )
    return campaign


# (case id, variant arguments, --strict needed, where the one line points, words it must contain)
PLAUSIBILITY_CASES = [
    (
        "temperature-in-degC",
        {"old": "temperature_k: 293.0", "new": "temperature_k: 20.0"},
        True,
        "vehicle.yaml:22: rcs.feed.temperature_k",
        ["20 K: a temperature in degC?"],
    ),
    (
        "truncnorm-excludes-nominal",
        {"dispersions": "mass_kg: {dist: truncnorm, sigma: 0.4, low: 25.0, high: 30.0}"},
        True,
        "campaign.yaml:7: dispersions.mass_kg.low",
        ["exclude the nominal 20"],
    ),
    (
        "pressure-in-bar-fails-the-reserve",
        {"old": "initial_pressure_pa: 5.0e6", "new": "initial_pressure_pa: 50.0"},
        False,  # an error with or without --strict: the shipped mission's reserve check
        "vehicle.yaml:23: rcs.feed.initial_pressure_pa",
        ["50 Pa: a pressure in bar", "surveyor-hop.yaml:18: local.reserve_pressure_pa"],
    ),
    (
        "missing-vehicle-file",
        {"vehicle": "my-vehicle.yaml"},
        False,
        "campaign.yaml:2: vehicle",
        ["vehicle: vehicle file 'my-vehicle.yaml' (relative to the campaign file's folder): file not found"],
    ),
]


@pytest.mark.parametrize(
    ("variant", "strict", "where", "words"), [c[1:] for c in PLAUSIBILITY_CASES], ids=[c[0] for c in PLAUSIBILITY_CASES]
)
def test_implausible_input_is_refused_at_the_users_key_and_writes_nothing(
    tmp_path, existing_out, variant, strict, where, words
):
    campaign = _hop_variant(tmp_path, **variant)
    before = _snapshot(existing_out)
    fresh = tmp_path / "fresh"
    flags = ["--strict"] if strict else []
    for args in (
        ["validate", *flags, str(campaign)],
        ["run", str(campaign), "-o", str(fresh), "--no-progress", *flags],
        ["run", str(campaign), "-o", str(existing_out), "--overwrite", "--no-progress", *flags],
    ):
        result = CliRunner().invoke(main, args)
        assert result.exit_code == 2, result.output
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in result.output, result.output
        assert lines[0].startswith(f"error: {tmp_path / where}"), lines[0]
        for word in words:
            assert word in lines[0], (word, lines[0])
    assert not fresh.exists()
    assert _snapshot(existing_out) == before
    if strict:  # without --strict: a warning, and the campaign validates
        result = CliRunner().invoke(main, ["validate", str(campaign)])
        assert result.exit_code == 0 and f"warning: {tmp_path / where}" in result.output, result.output


def test_a_missing_vehicle_file_is_named_once(tmp_path):
    """An absolute path the user wrote is printed once, after the campaign line that names it."""
    missing = tmp_path / "refexx.yaml"
    campaign = _hop_variant(tmp_path, vehicle=str(missing))
    result = CliRunner().invoke(main, ["validate", str(campaign)])
    assert result.exit_code == 2, result.output
    line = result.output.strip()
    assert line == f"error: {campaign}:2: vehicle: vehicle file '{missing}': file not found", line
    assert line.count(str(missing)) == 1


# --- sweeps (docs/studies.md sec. 2): a misspelt parameter path gets a did-you-mean ---------------


def test_a_misspelt_sweep_parameter_gets_did_you_mean(tmp_path):
    text = (ROOT / "campaigns/refex-propellant-sweep.yaml").read_text().replace("../configs/", f"{ROOT}/configs/")
    assert text.count("parameter: rcs.propellant_kg") == 1
    text = text.replace("parameter: rcs.propellant_kg", "parameter: rcs.propelant_kg")
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(text)
    line = next(n for n, s in enumerate(text.splitlines(), 1) if "parameter: rcs.propelant_kg" in s)
    result = CliRunner().invoke(main, ["validate", str(campaign)])
    assert result.exit_code == 2, result.output
    assert result.output.strip() == (
        f"error: {campaign}:{line}: sweep.axes.0.parameter: unknown parameter path 'rcs.propelant_kg'; "
        "did you mean 'rcs.propellant_kg'?"
    )


def test_a_vector_sweep_parameter_still_lists_the_scalar_paths(tmp_path):
    """A known path that is not a scalar: no guess (it is spelt right), the paths a sweep takes."""
    text = (ROOT / "campaigns/refex-propellant-sweep.yaml").read_text().replace("../configs/", f"{ROOT}/configs/")
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(text.replace("parameter: rcs.propellant_kg", "parameter: com_offset_m"))
    result = CliRunner().invoke(main, ["validate", str(campaign)])
    assert result.exit_code == 2, result.output
    assert "sweep.axes.0.parameter: expected a scalar parameter path (mass_kg," in result.output
    assert "got 'com_offset_m'" in result.output and "did you mean" not in result.output


# --- --until-decided on a rare-event study (docs/rare-events.md) ---------------------------------


def test_until_decided_into_an_existing_out_is_one_line_without_progress(tmp_path):
    """The run's own checks come after --until-decided's: its progress is shown only once runs fly."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    result = CliRunner().invoke(
        main, ["run", str(ROOT / "campaigns/refex-until-decided.yaml"), "--until-decided", "-o", str(out)]
    )
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and "output directory exists" in lines[0], result.output
    assert sorted(path.name for path in out.iterdir()) == ["notes.txt"]


@pytest.mark.parametrize("progress", [[], ["--no-progress"]])
def test_until_decided_on_a_rare_event_study_names_until_decided(tmp_path, progress):
    """Before: "--runs cannot be used with rare_event", --runs not given (run_until_decided's own
    runs= reached the overrides); and no progress line before the error."""
    out = tmp_path / "udx"
    result = CliRunner().invoke(
        main, ["run", str(ROOT / "campaigns/surveyor-hop-rare.yaml"), "--until-decided", "-o", str(out), *progress]
    )
    assert result.exit_code == 2, result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert "--until-decided" in result.output and "rare" in result.output, result.output
    assert "--runs" not in result.output, result.output
    assert not out.exists()
