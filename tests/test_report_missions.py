"""The report of every shipped mission is built from that mission: its requirements, its outputs, its words.

Each shipped campaign (ReFEx smoke, SPORE deorbit, IRASSI fine pointing, generic slew, the cold-gas
surveyor hop, the X-38 entry nominal and with a blocked flap) flies a few runs in-process and is reported; the
tests check, per mission, what a reader of another mission's report complained about (issue 25):
no other mission's words, a statistics row, a figure and a worst-case list for every requirement
metric, no figure axis without data, and the failure header as the runs table has it. The
Chromium test renders every page at 1400 px and checks that no table is wider than the page.
"""

import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axes import Axes
from stored import read_runs, store_campaign

from refexmc.config.load import apply_overrides, load_campaign
from refexmc.config.requirements import CAMPAIGN_METRICS, split_metric
from refexmc.report import make_report, stats

ROOT = Path(__file__).resolve().parents[1]
MISSIONS = {  # campaign file: runs flown here (enough for every requirement statistic to be computable)
    "smoke.yaml": 8,
    "spore-deorbit-iss.yaml": 8,
    "irassi-fine-pointing.yaml": 10,
    "generic-slew.yaml": 8,
    "surveyor-hop.yaml": 8,
    "x38-blocked-flap.yaml": 8,
    "x38-nominal.yaml": 8,
}
REFEX_ONLY = re.compile(r"hand-?over|separation|000 (Fig|Table|sec)\.?", re.I)  # keys and columns too (issue 34)


def axes_without_data(figure):
    """Titles (or positions) of the axes of ``figure`` (subfigures included) that hold no data in
    both directions: a requirement line alone (axhline/axvline) leaves x or y without data."""
    empty = []
    for k, ax in enumerate(figure.findobj(Axes)):
        if not ax.get_visible():
            continue
        if not np.isfinite(ax.dataLim.get_points()).all():
            empty.append(ax.get_title() or f"axes {k}")
    return empty


def record_figures(monkeypatch):
    """Record, for every figure the report renders, its axes without data, y-labels and horizontal lines."""
    from refexmc.report import figures

    recorded = []
    render = figures.png

    def recording(figure):
        axes = figure.findobj(Axes)
        recorded.append(
            {
                "empty": axes_without_data(figure),
                "ylabels": [ax.get_ylabel() for ax in axes],
                "xlabels": [ax.get_xlabel() for ax in axes],
                "hlines": sorted(
                    {
                        round(float(line.get_ydata()[0]), 9)
                        for ax in axes
                        for line in ax.get_lines()
                        if len(line.get_ydata()) == 2 and line.get_ydata()[0] == line.get_ydata()[1]
                    }
                ),
            }
        )
        return render(figure)

    monkeypatch.setattr(figures, "png", recording)
    return recorded


@pytest.fixture(scope="module", params=list(MISSIONS))
def mission(request, tmp_path_factory):
    """(campaign file name, OUT, report, recorded figures, page text without images) of one mission."""
    name = request.param
    campaign = apply_overrides(load_campaign(ROOT / "campaigns" / name), runs=MISSIONS[name])
    if "wheel_failures" in campaign and campaign["wheel_failures"].get("mode") == "random":
        # more failed wheels than the shipped 20 % so that a few runs show both kinds of set
        campaign["wheel_failures"]["count_probabilities"] = [0.5, 0.5]
    out = tmp_path_factory.mktemp(name.replace(".yaml", "")) / "out"
    store_campaign(campaign, out)
    monkeypatch = pytest.MonkeyPatch()
    try:
        recorded = record_figures(monkeypatch)
        report = make_report(out, html=True)
    finally:
        monkeypatch.undo()
    page = (out / "report" / "index.html").read_text()
    page = re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]*", "", page)
    return name, out, report, recorded, page


def requirement_columns(report):
    columns = []
    for r in report["requirements"]:
        if r.get("kind") == "pointing":  # a pointing record judges its runs column (docs/pointing.md)
            if r["metric"] not in columns:
                columns.append(r["metric"])
            continue
        if r["metric"] not in CAMPAIGN_METRICS and split_metric(r["metric"])[0] not in columns:
            columns.append(split_metric(r["metric"])[0])
    return columns


@pytest.mark.slow
def test_no_words_of_another_mission(mission):
    name, out, report, _, page = mission
    refex = name == "smoke.yaml"
    json_text = (out / "report" / "summary.json").read_text()
    for where, text in (("text", report["text"]), ("index.html", page), ("summary.json", json_text)):
        found = REFEX_ONLY.search(text)
        if refex:
            continue
        assert not found, (
            f"{name} {where}: ReFEx's words {found.group()!r} in ...{text[found.start() - 80 : found.end() + 40]}"
        )
    if refex:  # ReFEx keeps 000's words and figure numbers
        assert "000 Fig. 11 analogue" in page and "hand-over" in page


@pytest.mark.slow
def test_every_requirement_metric_has_a_row_a_figure_and_a_worst_case_list(mission):
    name, _, report, _, page = mission
    summary = report["summary"]
    columns = requirement_columns(report)
    assert columns, f"{name}: every shipped campaign has requirements on runs columns"
    # the same columns, in the campaign file's order (tests/test_report_pointing_records.py checks the order)
    assert sorted(summary["outputs"]["requirement_columns"]) == sorted(columns)
    runs = read_runs(mission[1])
    successful = runs[(runs["status"] == "ok") & runs["success"]]
    for column in columns:
        row = summary["columns"][column]
        values = successful[column].to_numpy(dtype=float)
        assert row["n"] == np.isfinite(values).sum() and row["median"] == pytest.approx(np.nanmedian(values))
        assert f"<code>{column}</code>" in page
        assert summary["metric_figures"].get(column) == "metrics", f"{name}: no figure of {column}"
        lists = [w for w in summary["worst_cases"].values() if w.get("column") == column]
        assert lists and all(w["runs"] for w in lists), f"{name}: no worst-case list of {column}"
        side = lists[0]["side"]
        worst = lists[0]["runs"][0][column]
        assert worst == (np.nanmin if side == "low" else np.nanmax)(runs.loc[runs["status"] == "ok", column])
    # the statistics tables: requirement metrics first; no per-thruster pulse rows, constants in one line
    assert not any(re.fullmatch(r"pulses_\d+", c) for c in summary["outputs"]["other_columns"])
    for column, value in summary["outputs"]["constant_columns"].items():
        assert (successful[column].to_numpy(dtype=float) == value).all()
        assert f"{column} = " in page


@pytest.mark.slow
def test_no_figure_axis_without_data(mission):
    name, _, report, recorded, _ = mission
    assert len(recorded) == len(report["summary"]["figures"]) >= 3
    for title, figure in zip(report["summary"]["figures"], recorded, strict=True):
        assert not figure["empty"], f"{name}: figure {title!r} has axes without data: {figure['empty']}"


def test_the_empty_axis_check_can_fail():
    from matplotlib.figure import Figure

    figure = Figure()
    left, right = figure.subplots(1, 2)
    left.hist([1.0, 2.0, 2.5])
    right.axhline(0.4)  # a requirement line alone: no data
    right.set_title("empty")
    assert axes_without_data(figure) == ["empty"]


@pytest.mark.slow
def test_failure_header_matches_the_runs_table(mission):
    name, out, report, _, page = mission
    runs = read_runs(out)
    expected = {}
    for column, kind in (("failed_thrusters", "thruster"), ("failed_wheels", "wheel")):
        if column in runs:
            count = int((runs[column].fillna("").astype(str) != "").sum())
            if count:
                expected[kind] = count
    blocked = "p.entry_flight.blocked_flap.deflection_deg"
    if blocked in runs:  # an entry with a blocked flap: every run flies with it
        expected["body flap"] = int(np.isfinite(runs[blocked].to_numpy(dtype=float)).sum())
    kinds = {k["kind"]: k["runs_with_failure"] for k in report["summary"]["campaign"]["failure_kinds"]}
    assert {k: v for k, v in kinds.items() if v} == expected
    # whether the flight software knew failed thrusters: none without them (an X-38 flap says its own)
    thrusters = (load_campaign(ROOT / "campaigns" / name).get("failures") or {}).get("mode", "none") != "none"
    assert (report["summary"]["campaign"]["failures_detected"] is None) is not thrusters
    header = report["summary"]["campaign"]["failures"]
    if name == "irassi-fine-pointing.yaml":
        assert expected.get("wheel", 0) > 0, "the test campaign must fail some wheels"
        assert f"wheels random, undetected ({expected['wheel']} of {len(runs)} runs with a failed wheel)" == header
        assert f"failures: {header}" in page and f"failures: {header}" in report["text"]
    elif name == "x38-blocked-flap.yaml":
        drawn = runs[blocked].to_numpy(dtype=float)
        assert header == (
            "right body flap blocked, dispersed (uniform low 10, high 20), "
            f"drawn {drawn.min():.4g}-{drawn.max():.4g}°, nominal 14°, known to the flight software "
            f"({len(runs)} of {len(runs)} runs with a blocked flap)"
        )
        assert f"failures: {header}" in page and f"failures: {header}" in report["text"]
    elif not expected:
        assert header == "none"


@pytest.mark.slow
@pytest.mark.parametrize("mission", ["irassi-fine-pointing.yaml"], indirect=True)
def test_irassi_in_arcsec_with_sensitivity_and_wheel_sets_judged(mission):
    name, out, report, recorded, page = mission
    summary = report["summary"]
    modes = recorded[summary["figures"].index("Angle and rate errors per mode")]
    assert "total angle error θ_t [arcsec]" in modes["ylabels"]
    assert 0.4 in modes["hlines"]  # 001 Table 1's 0.4 arcsec
    # one history sample per 600 s cannot draw the 200-400 s manoeuvre: said, not drawn empty
    # (store_campaign writes no manifest: the mode names come upper-cased from the runs table)
    assert [m.lower() for m in summary["mode_panels"]["left_out"]["theta_t_deg"]] == ["manoeuvre"]
    assert [m.lower() for m in summary["mode_panels"]["shown"]["theta_t_deg"]] == ["science"]
    assert "Left out of the angle row for too few samples (history every 600 s): MANOEUVRE (1.0 per run)" in page
    sensitivity = summary["sensitivity"]
    for column in ("wheel_momentum_peak_n_m_s", "wheel_saturated_s"):  # the requirement metrics
        assert sensitivity[column], f"no sensitivity of {column}"
    runs = read_runs(out)
    ok = runs[runs["status"] == "ok"]
    metric = "wheel_saturated_s.p99"
    for row in summary["wheel_failure_sets"]["sets"]:
        group = ok[ok["failed_wheels"] == row["failed_wheels"]]
        values = group.loc[group["success"], "wheel_saturated_s"].to_numpy(dtype=float)
        failing = int((~group["success"]).sum())
        expected = stats.column_stat_with_failing(values, failing, "p99", "high")
        assert row[metric] == pytest.approx(expected)
        assert row["verdicts"][metric] == (expected <= 600.0)
        assert row["passed"] == (all(row["verdicts"].values()) and row["successes"] == row["runs"])
    assert '<td class="failing-cell">' in page or all(r["passed"] for r in summary["wheel_failure_sets"]["sets"])


def test_failed_wheel_table_tells_a_failing_cell_from_a_failing_row():
    """A set that fails one requirement: its row pale red, the failing statistic's cell deep red."""
    from refexmc.report.html import STYLE, wheel_failure_sets_section

    stat = "pointing_max_arcsec.p99"
    sets = [
        {"failed_wheels": "", "runs": 90, "successes": 90, stat: 0.2, "verdicts": {stat: True}, "passed": True},
        {"failed_wheels": "1", "runs": 10, "successes": 10, stat: 0.9, "verdicts": {stat: False}, "passed": False},
    ]
    page = wheel_failure_sets_section(
        {"statistics": [stat], "requirements": {stat: f"{stat} <= 0.4"}, "sets": sets, "detected": False}
    )
    rows = re.findall(r"<tr(?: class=\"([^\"]*)\")?>(.*?)</tr>", page)
    assert [cls for cls, _ in rows[1:]] == ["pass", "failing-row"]
    assert rows[2][1].count('class="failing-cell"') == 1 and '<td class="failing-cell">0.9' in rows[2][1]
    colours = dict(re.findall(r"(tr\.failing-row|td\.failing-cell)[^{]*\{ background: (#[0-9a-f]{6})", STYLE))
    assert colours["tr.failing-row"] != colours["td.failing-cell"]


PAGE_WIDTH = 1400
WIDTH_PROBE = """
<script>
window.addEventListener("load", () => {
  const tables = Array.from(document.querySelectorAll("table"), (t) => Math.ceil(t.getBoundingClientRect().right));
  const out = document.createElement("pre");
  out.id = "refexmc-width-probe";
  out.textContent = JSON.stringify({inner: window.innerWidth, scroll: document.documentElement.scrollWidth, tables});
  document.body.appendChild(out);
});
</script>
"""


@pytest.mark.slow
def test_no_table_wider_than_the_page_in_chromium(mission, tmp_path):
    import json

    from test_report_render import run_chromium

    binary = shutil.which("chromium")
    if binary is None:
        pytest.skip("needs Debian's chromium (apt-get install chromium)")
    name, out, _, _, _ = mission
    page = (out / "report" / "index.html").read_text()
    path = tmp_path / "index.html"
    path.write_text(page.replace("</body>", WIDTH_PROBE + "</body>"))
    dom = run_chromium(
        binary,
        tmp_path,
        f"--window-size={PAGE_WIDTH},1000",
        "--virtual-time-budget=10000",
        "--dump-dom",
        path.as_uri(),
    )
    found = re.search(r'<pre id="refexmc-width-probe">(.*?)</pre>', dom, re.S)
    assert found, "the probe did not report"
    result = json.loads(found.group(1))
    assert result["inner"] == PAGE_WIDTH and result["tables"], result
    assert max(result["tables"]) <= result["inner"], f"{name}: a table overflows the page: {result}"
    assert result["scroll"] <= result["inner"], f"{name}: the page scrolls sideways: {result}"


ENTRY_FIGURES = {  # title -> the panels (history signals) it must draw, each with data
    "Attitude tracking: α, β and bank μ against their commands": (
        "alpha_deg",
        "bank_deg",
        "alpha_error_deg",
        "beta_deg",
        "bank_error_deg",
    ),
    "Dynamic pressure, load factor, heat flux and the altitude-velocity corridor": (
        "qbar_pa",
        "load_factor_g",
        "heat_flux_w_m2",
        "altitude_over_speed_m",
    ),
    "Surface deflections and RCS propellant": ("flap_left_deg", "flap_right_deg", "rudder_deg", "rcs_propellant_kg"),
}


@pytest.mark.slow
@pytest.mark.parametrize("mission", ["x38-blocked-flap.yaml", "x38-nominal.yaml"], indirect=True)
def test_the_entry_report_draws_the_histories_with_bands_that_hold_the_nominal(mission):
    """Issue 24: an entry's report shows α, β, μ against their commands, q̄, load factor, heat flux,
    altitude-velocity, the surfaces and the RCS propellant over time, from the OUT's history
    columns; every band holds every flown run (the nominal run 0 included) and the blocked flap
    shows as a flat band at the drawn deflections."""
    import pyarrow.parquet as pq

    from refexmc.report import data, entry_histories

    name, out, report, recorded, page = mission
    summary = report["summary"]
    for title, panels in ENTRY_FIGURES.items():
        assert title in summary["figures"], f"{name}: no figure {title!r}"
        figure = recorded[summary["figures"].index(title)]
        assert not figure["empty"] and len(figure["ylabels"]) == len(panels)
        assert "time since the entry interface [s]" in figure["xlabels"]
        assert f"<h2>{title}</h2>" in page
    assert summary["entry_panels"]["shown"] == [p for panels in ENTRY_FIGURES.values() for p in panels]
    tracking = recorded[summary["figures"].index(next(iter(ENTRY_FIGURES)))]
    if name == "x38-blocked-flap.yaml":  # its alpha transients reach the 1 deg bound (the nominal's stay far below)
        assert 1.0 in tracking["hlines"] and -1.0 in tracking["hlines"]  # alpha_error_max_deg.max < 1, drawn at +-1
    # the envelopes against the history read whole, run by run (the few runs of this test)
    campaign = data.load(out)
    aggregate = entry_histories.aggregate_entry_histories(campaign)
    history = pq.read_table(sorted((out / "histories").glob("*.parquet"))).to_pandas()
    assert aggregate["rows"] == len(history)
    for signal in ("alpha_error_deg", "qbar_pa", "flap_right_deg", "rcs_propellant_kg"):
        envelope, q = aggregate["signals"][signal]
        columns = entry_histories.ENTRY_SIGNALS[signal][0]
        compute = entry_histories.ENTRY_SIGNALS[signal][1]
        frame = {c: history[c].to_numpy(dtype=float) for c in columns}
        values = compute(frame) if compute else frame[columns[0]]
        bins = envelope.bin_of(history["t_s"].to_numpy())  # centred on multiples of dx
        for b in np.unique(bins)[:: max(1, len(np.unique(bins)) // 50)]:
            here = values[bins == b]
            # min and max are exact; the percentiles lie between them
            assert q[b, 0] == here.min() and q[b, 4] == here.max(), (signal, b)
            assert q[b, 0] <= q[b, 1] <= q[b, 2] <= q[b, 3] <= q[b, 4]
        nominal = aggregate["nominal"]
        mine = envelope.bin_of(nominal["t_s"])
        assert (q[mine, 0] <= nominal[signal]).all() and (nominal[signal] <= q[mine, 4]).all()
    right = aggregate["signals"]["flap_right_deg"][1]
    runs = read_runs(out)
    if name == "x38-blocked-flap.yaml":  # the blocked flap: a flat band over the drawn deflections
        drawn = runs["p.entry_flight.blocked_flap.deflection_deg"].to_numpy(dtype=float)
        all_flying = np.arange(len(right)) * aggregate["signals"]["flap_right_deg"][0].dx < runs["t_end_s"].min() - 5
        assert all_flying.sum() > 100
        assert (right[all_flying, 0] == np.float32(drawn.min())).all()  # the history is float32
        assert (right[all_flying, 4] == np.float32(drawn.max())).all()
        assert "The right body flap blocked, dispersed (uniform low 10, high 20), drawn" in page
    else:  # both flaps free: they leave 0 together once below the RCS-only altitude
        assert summary["campaign"]["failures"] == "none"
        left = aggregate["signals"]["flap_left_deg"][1]
        assert np.nanmax(left[:, 4]) > 1.0 and np.nanmax(right[:, 4]) > 1.0
        assert np.nanmin(left[:, 0]) == 0.0 and np.nanmin(right[:, 0]) == 0.0  # held at 0 above 90 km


@pytest.mark.slow
@pytest.mark.parametrize("mission", ["x38-blocked-flap.yaml", "x38-nominal.yaml"], indirect=True)
def test_the_entry_figures_render_in_chromium(mission, tmp_path):
    """Chromium loads and draws every figure of the entry report, the history figures among them."""
    from test_report_render import figures_drawn, probe

    binary = shutil.which("chromium")
    if binary is None:
        pytest.skip("needs Debian's chromium (apt-get install chromium)")
    name, out, report, _, _ = mission
    titles = report["summary"]["figures"]
    result = probe(binary, (out / "report" / "index.html").read_text(), tmp_path)
    assert result["alts"] == titles and set(ENTRY_FIGURES) <= set(result["h2"])
    assert figures_drawn(result) == [True] * len(titles), (name, result)
    assert all(w > 100 and h > 100 for w, h in result["shown"]), result["shown"]


@pytest.mark.parametrize(
    ("where", "blocked", "dispersion", "expected"),
    [
        (
            "mission",
            {"flap": "right", "deflection_deg": 14.0, "known_to_flight_software": True},
            {"dist": "uniform", "low": 10.0, "high": 20.0},
            "right body flap blocked, dispersed (uniform low 10, high 20), drawn 10.5-19.5°, nominal 14°, "
            "known to the flight software (3 of 3 runs with a blocked flap)",
        ),
        (
            "mission",
            {"flap": "left", "deflection_deg": 12.0, "known_to_flight_software": False},
            None,
            "left body flap blocked, fixed at 12°, unknown to the flight software (3 of 3 runs with a blocked flap)",
        ),
        (
            "vehicle",
            {"flap": "right", "deflection_deg": 16.0},
            None,
            "right body flap blocked, fixed at 16°, known to the flight software (3 of 3 runs with a blocked flap)",
        ),
        ("none", None, None, None),
    ],
)
def test_the_failure_header_names_the_blocked_flap(tmp_path, where, blocked, dispersion, expected):
    """Which flap, fixed or dispersed (with the range the runs drew), known to the flight software
    or not; from the mission's entry_flight.blocked_flap or the vehicle file's body_flaps.blocked."""
    import pandas as pd

    from refexmc.report import data, summary

    runs = pd.DataFrame({"run_id": [0, 1, 2], "status": "ok", "success": True})
    mission = {"entry_flight": {"state": {}}}
    vehicle = {"surfaces": {"body_flaps": {"min_deg": -20.0, "max_deg": 30.0}}}
    resolved = {"mission": mission, "vehicle": vehicle, "failures": {"mode": "none"}}
    if where == "mission":
        mission["entry_flight"]["blocked_flap"] = blocked
    elif where == "vehicle":
        vehicle["surfaces"]["body_flaps"]["blocked"] = blocked
    if dispersion:
        resolved["dispersions"] = {"entry_flight.blocked_flap.deflection_deg": dispersion}
        runs["p.entry_flight.blocked_flap.deflection_deg"] = [14.0, 10.5, 19.5]
    campaign = data.Campaign(out=tmp_path, runs=runs, resolved=resolved, resolved_lines={})
    kinds = summary.failures_section(campaign)
    if expected is None:
        assert kinds == []
        return
    (kind,) = kinds
    assert kind["text"] == expected
    assert kind["kind"] == "body flap" and kind["flap"] == blocked["flap"]
    assert kind["mode"] == ("dispersed" if dispersion else "fixed")
    assert kind["detected"] == blocked.get("known_to_flight_software", True)
    assert kind["drawn_deg"] == ([10.5, 19.5] if dispersion else None)


@pytest.mark.slow
@pytest.mark.parametrize("mission", ["surveyor-hop.yaml"], indirect=True)
def test_the_hop_report_draws_distance_speed_and_tank_pressure_with_their_bounds(mission):
    """Issue 34: a hop's report shows how the runs drifted to the target (distance, speed,
    position) and how the tank emptied, each with its requirement bound; no attitude figure."""
    name, _, report, recorded, page = mission
    summary = report["summary"]
    titles = summary["figures"]
    assert "Angle and rate errors per mode" not in titles  # the hop controls no attitude
    translation = recorded[titles.index("Distance to the target, speed and position")]
    assert not translation["empty"]
    assert {"distance to the target [m]", "speed [m/s]", "position x (local frame) [m]"} <= set(translation["ylabels"])
    assert "time since the start of the flight [s]" in translation["xlabels"]
    assert 0.05 in translation["hlines"]  # position_error_end_m.p95 <= 0.05
    tank = recorded[titles.index("Tank pressure")]
    assert not tank["empty"] and tank["ylabels"] == ["tank pressure [Pa]"]
    assert 1.0e6 in tank["hlines"]  # tank_pressure_end_pa.p5 >= 1.0e6
    assert summary["family_panels"]["shown"] == [
        "position_error_m",
        "speed_m_s",
        "position_x_m",
        "position_y_m",
        "position_z_m",
        "tank_pressure_pa",
    ]
    assert "The target of the mission: (3, 1, 0) m." in page


@pytest.mark.slow
@pytest.mark.parametrize("mission", ["irassi-fine-pointing.yaml"], indirect=True)
def test_the_irassi_report_draws_each_wheels_momentum_and_torque(mission):
    name, _, report, recorded, _ = mission
    titles = report["summary"]["figures"]
    wheels = recorded[titles.index("Reaction wheel momenta and motor torques")]
    assert not wheels["empty"]
    assert wheels["ylabels"] == [f"wheel {i} momentum I_w Ω [N m s]" for i in range(1, 5)] + [
        f"wheel {i} motor torque [N m]" for i in range(1, 5)
    ]
    assert {68.0, -68.0} <= set(wheels["hlines"])  # wheel_momentum_peak_n_m_s.max < 68, at +-
    assert "Tank pressure" not in titles and "Propellant remaining" not in titles
