"""`make_report` on constructed campaign outputs: every number against an independent computation."""

import base64
import json
import re
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from scipy import stats as sps

from refexmc.campaign import storage
from refexmc.config.errors import ConfigError
from refexmc.report import make_report, stats
from refexmc.report.requirements import parse_requirement

ROOT = Path(__file__).resolve().parents[1]
# the ReFEx modes and a typical time in each [s]; as in real flights NCM coasts (no control: no angle
# error, no valve opens) and RDM1 and RDM2 damp the rates (valves open, no attitude reference: no angle error)
REFEX_MODES = {"NCM": 5.0, "RDM1": 10.0, "SAM": 30.0, "SSM": 120.0, "RDM2": 8.0, "EAM": 40.0, "GEEM": 15.0}
REFEX_WITHOUT_ANGLE_ERROR = ("NCM", "RDM1", "RDM2")
REFEX_COASTING = ("NCM",)
MODE_COLUMNS = [f"t_{name.lower()}_s" for name in REFEX_MODES]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def synthetic_runs(n=60, errored=(7, 23), failed=(3, 11, 40), sets=None, seed=1, modes=REFEX_MODES):
    """Rows of a runs table: known columns, two p. parameters (one drives the propellant).

    ``modes``: {mode name: typical seconds in it}, in flight order.
    """
    rng = np.random.default_rng(seed)
    mode_columns = [f"t_{name.lower()}_s" for name in modes]
    mode_seconds = np.array(list(modes.values()))
    failure = f"{list(modes)[min(2, len(modes) - 1)].lower()}_timeout"
    rows = []
    for i in range(n):
        drive = 1.0 if i == 0 else rng.normal(1.0, 0.1)
        noise = 0.5 if i == 0 else rng.uniform(0, 1)
        fuel = 0.5 - 0.3 * (drive - 1.0) + 0.01 * rng.normal()
        times = mode_seconds * (1.0 if i == 0 else rng.uniform(0.9, 1.1, len(mode_seconds)))
        row = {
            "run_id": i,
            "seed": 1000 + i,
            "status": "ok",
            "success": i not in failed,
            "failure_reason": failure if i in failed else None,
            "failed_thrusters": sets[i] if sets else "",
            "fuel_remaining": fuel,
            "fuel_used_kg": 1.96 * (1 - fuel),
            "t_end_s": float(times.sum()),
            **{c: float(t) for c, t in zip(mode_columns, times, strict=True)},
            "attitude_error_end_deg": float(rng.uniform(0.05, 1.0)),
            "modes_completed": len(modes),
            **{f"pulses_{k}": int(rng.integers(50, 150)) for k in range(1, 9)},
            "p.rcs.isp_s": 70.0 * drive,
            "p.navigation.rate_noise_deg_s": 0.02 * noise,
        }
        if i in errored:  # an errored run: absurd finite values that must not reach any statistic
            row.update(status="error", success=False, failure_reason="RuntimeError: boom", fuel_remaining=-5.0)
            row["attitude_error_end_deg"] = 1e6
        rows.append(row)
    return rows


def synthetic_history(
    row, rate_hz=2.0, modes=REFEX_MODES, without_angle_error=REFEX_WITHOUT_ANGLE_ERROR, coasting=REFEX_COASTING
):
    """Samples of one run: theta_t = 100 exp(-tau) (tau: time since mode start), NaN in the modes
    ``without_angle_error``; valves 1 and 2 open (mask 3) except in the ``coasting`` modes."""
    names = list(modes)
    times = np.array([row[f"t_{name.lower()}_s"] for name in names])
    starts = np.concatenate([[0.0], np.cumsum(times)[:-1]])
    t = np.arange(0.0, row["t_end_s"], 1.0 / rate_hz)
    mode = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(names) - 1)
    tau = t - starts[mode]
    n = len(t)
    mode_name = np.array(names)[mode]
    theta = np.where(np.isin(mode_name, without_angle_error), np.nan, 100.0 * np.exp(-tau))
    valves = np.where(np.isin(mode_name, coasting), 0, 3).astype(np.int32)
    return pa.table(
        {
            "run_id": pa.array(np.full(n, row["run_id"], dtype=np.int64)),
            "t_s": pa.array(t),
            "mode": pa.DictionaryArray.from_arrays(pa.array(mode.astype(np.int32)), pa.array(names)),
            "theta_t_deg": pa.array(theta),
            "omega_m_deg_s": pa.array(np.full(n, 2.0)),
            "fuel_remaining": pa.array(1.0 - (1.0 - row["fuel_remaining"]) * t / row["t_end_s"]),
            "valves_open": pa.array(valves),
        }
    )


def write_out(
    out,
    rows,
    requirements=(),
    nominal_first=True,
    histories=True,
    parts=2,
    modes=REFEX_MODES,
    without_angle_error=REFEX_WITHOUT_ANGLE_ERROR,
    coasting=REFEX_COASTING,
    vehicle="refex",
):
    """An OUT directory as `refexmc run` writes it (runs and histories in `parts` part files)."""
    storage.prepare_output(out)
    campaign = {
        "name": "synthetic",
        "runs": len(rows),
        "seed": 5,
        "nominal_first": nominal_first,
        "sampling": "random",
        "failures": {"mode": "none"},
        "output": {"history_rate_hz": 2.0},
        "requirements": list(requirements),
        "vehicle": {"name": vehicle},
    }
    storage.write_resolved(out, campaign)
    storage.write_manifest(out, {"name": "synthetic", "status": "complete", "refexmc": "test", "modes": list(modes)})
    bounds = np.linspace(0, len(rows), parts + 1).astype(int)
    for k in range(parts):
        chunk = rows[bounds[k] : bounds[k + 1]]
        storage.write_table_atomic(storage.runs_table(chunk), out / "runs" / storage.part_name(k))
        if histories:
            flown = [r for r in chunk if r["status"] == "ok"]
            tables = [synthetic_history(r, 2.0, modes, without_angle_error, coasting) for r in flown]
            storage.write_table_atomic(pa.concat_tables(tables), out / "histories" / storage.part_name(k))
    return out


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    rows = synthetic_runs()
    out = write_out(
        tmp_path_factory.mktemp("report") / "out",
        rows,
        requirements=["fuel_remaining.min >= 0.20", "success_rate >= 1.0"],
    )
    report = make_report(out, require=["attitude_error_end_deg.p99 <= 2.0", "pulses_total.p50 <= 2000"], html=True)
    return out, rows, report


def ok_values(rows, column):
    return np.array([r[column] for r in rows if r["status"] == "ok"], dtype=float)


def successful_values(rows, column):
    return np.array([r[column] for r in rows if r["status"] == "ok" and r["success"]], dtype=float)


def test_success_rate_counts_errored_runs_as_unsuccessful(synthetic):
    _, rows, report = synthetic
    s = report["summary"]
    assert s["counts"] == {"runs": 60, "ok_count": 58, "error_count": 2, "success_count": 55, "failure_count": 3}
    expected = sps.binomtest(55, 60).proportion_ci(confidence_level=0.95, method="exact")
    assert s["success"]["rate"] == pytest.approx(55 / 60)
    assert s["success"]["ci95"] == pytest.approx([expected.low, expected.high], abs=1e-12)
    lower = sps.binomtest(55, 60, alternative="greater").proportion_ci(method="exact").low
    assert s["metrics"]["success_rate_lower95"] == pytest.approx(lower, abs=1e-12)
    assert s["success"]["covers"] == "all 60 runs (2 errored runs count as unsuccessful)"
    assert "5 of 60 runs did not succeed (3 failed, 2 errored)" in s["success"]["statement"]


def test_share_of_dispersed_runs_using_more_propellant_than_the_nominal(synthetic):
    """000 sec. 6.2 / Fig. 12 says "most" runs use more than the nominal one: the report counts them
    over the flown dispersed runs (errored runs have no flight to compare)."""
    _, rows, report = synthetic
    nominal = rows[0]["fuel_used_kg"]
    flown = [r for r in rows[1:] if r["status"] == "ok"]
    more = sum(r["fuel_used_kg"] > nominal for r in flown)
    against = report["summary"]["nominal"]["propellant_used_vs_dispersed"]
    assert (against["more_than_nominal"], against["of"]) == (more, len(flown)) == (against["more_than_nominal"], 57)
    assert 0 < more < len(flown)
    assert f"dispersed runs using more propellant than the nominal run: {more} of 57" in report["text"]


def test_column_statistics_match_numpy_over_successful_flights(synthetic):
    _, rows, report = synthetic
    columns = report["summary"]["columns"]
    fuel = successful_values(rows, "fuel_remaining")
    f = columns["fuel_remaining"]
    assert f["count"] == f["n"] == 55  # neither the 3 failed flights nor the 2 errored runs
    assert f["covers"] == "55 successful flights; 5 of 60 runs not included (failed or errored)"
    assert f["min"] == fuel.min()  # the errored run's -5.0 is excluded
    for percent in (0.135, 1, 5):
        assert f[f"p{percent:g}"] == pytest.approx(np.percentile(fuel, percent), abs=1e-15)
    assert f["median"] == pytest.approx(np.median(fuel), abs=1e-15)
    assert f["mean"] == pytest.approx(fuel.mean())
    assert f["mean_minus_3sd"] == pytest.approx(fuel.mean() - 3 * fuel.std(ddof=1))
    k = stats.normal_tolerance_factor(55)
    assert f["tol_lower"] == pytest.approx(fuel.mean() - k * fuel.std(ddof=1))
    assert f["p0.135_lower95"] is None  # 55 runs cannot bound the 0.135th percentile (needs 2218)
    k99 = stats.normal_tolerance_factor(55, 0.99)  # 55 < 299: the normal bound, not an order statistic
    assert f["tolerance_99_95"] == pytest.approx(fuel.mean() - k99 * fuel.std(ddof=1))
    assert f["tolerance_99_95_method"].startswith("normal: mean - 2.8")
    theta = successful_values(rows, "attitude_error_end_deg")
    t = columns["attitude_error_end_deg"]
    assert t["max"] == theta.max()  # not the errored run's 1e6
    for percent in (95, 99, 99.865):
        assert t[f"p{percent:g}"] == pytest.approx(np.percentile(theta, percent), abs=1e-15)
    assert t["mean_plus_3sd"] == pytest.approx(theta.mean() + 3 * theta.std(ddof=1))
    assert t["tolerance_99_95"] == pytest.approx(theta.mean() + k99 * theta.std(ddof=1))
    for name in MODE_COLUMNS:
        assert columns[name]["median"] == pytest.approx(np.median(successful_values(rows, name)))
    pulses = sum(successful_values(rows, f"pulses_{k}") for k in range(1, 9))
    assert columns["pulses_total"]["max"] == pulses.max()
    assert columns["pulses_3"]["mean"] == pytest.approx(successful_values(rows, "pulses_3").mean())


def test_each_column_shows_its_worse_tail_and_no_negative_bounds_on_angles_or_durations(synthetic):
    _, rows, report = synthetic
    columns = report["summary"]["columns"]
    expected = {
        "fuel_remaining": "lower",
        "fuel_used_kg": "upper",
        "attitude_error_end_deg": "upper",
        "t_end_s": "upper",
        "t_sam_s": "upper",
        "pulses_total": "upper",
        "pulses_5": "upper",
    }
    assert {c: columns[c]["tail"] for c in expected} == expected
    theta = successful_values(rows, "attitude_error_end_deg")
    assert theta.mean() - 3 * theta.std(ddof=1) < 0  # what the old lower-tail table printed for an angle
    for column, values in columns.items():
        if values["tail"] == "upper":
            assert not {"min", "p1", "p0.135", "mean_minus_3sd", "tol_lower"} & set(values), column
            numbers = [v for v in values.values() if isinstance(v, float)]
            assert min(numbers) >= 0, f"{column}: a negative statistic of a non-negative quantity"
        else:
            assert not {"max", "p99", "p99.865", "mean_plus_3sd", "tol_upper"} & set(values), column
    lines = report["text"].splitlines()
    upper = lines.index("larger is worse (upper tail):")
    lower = lines.index("smaller is worse (lower tail):")
    assert lines[upper + 1].split() == ["n", "p50", "mean", "p99", "p99.865", "max", "mean+3sd", "tol99/95"]
    assert lines[lower + 1].split() == ["n", "p50", "mean", "p1", "p0.135", "min", "mean-3sd", "tol99/95"]
    # the requirements' metrics first (attitude_error_end_deg and pulses_total by --require), then the others
    assert lines[upper + 2].split()[:2] == ["attitude_error_end_deg", "55"]
    assert lines[upper + 3].split()[:2] == ["pulses_total", "55"]
    assert lines[upper + 4].split()[:2] == ["fuel_used_kg", "55"]
    assert lines[lower + 2].split()[:2] == ["fuel_remaining", "55"]
    assert "  over 55 successful flights; 5 of 60 runs not included (failed or errored)" in lines


def test_requirement_verdicts_and_sources(synthetic):
    _, rows, report = synthetic
    verdicts = report["requirements"]
    assert [v["requirement"] for v in verdicts] == [
        "fuel_remaining.min >= 0.20",
        "success_rate >= 1.0",
        "attitude_error_end_deg.p99 <= 2.0",
        "pulses_total.p50 <= 2000",
    ]
    assert [v["source"] for v in verdicts] == ["campaign", "campaign", "--require", "--require"]
    # 3 failed flights and 2 errored runs fail the minimum, and 5 of 60 are more than the 1 % a p99 may hold
    assert [v["passed"] for v in verdicts] == [False, False, False, True]
    assert verdicts[0]["actual"] is None
    assert verdicts[0]["actual_successful_flights"] == successful_values(rows, "fuel_remaining").min()
    assert verdicts[0]["failing_run_ids"] == [3, 7, 11, 23, 40] and verdicts[0]["failing_count"] == 5
    assert verdicts[0]["covers"] == (
        "all 60 runs: 55 successful flights; failed flights 3, 11, 40 and errored runs 7, 23 count as failing"
    )
    assert verdicts[3]["actual"] < 2000 and "5 failing runs ranked at the high end" in verdicts[3]["note"]
    assert report["passed"] is False and report["verdict"] == "ERRORED"
    text = report["text"]
    assert "FAIL  fuel_remaining.min >= 0.20" in text
    assert "fails because of the failed flights 3, 11, 40 and errored runs 7, 23" in text
    assert "met   pulses_total.p50 <= 2000" in text
    assert "verdict: ERRORED (1 of 4 requirements met)" in text
    assert "PASS" not in text  # errored runs: no PASS, not even for the requirement that holds


def test_summary_json_is_strict_json_with_the_report(synthetic):
    out, _, report = synthetic
    text = (out / "report" / "summary.json").read_text()
    data = json.loads(text, parse_constant=lambda name: pytest.fail(f"non-strict JSON constant {name}"))
    assert data == report["summary"]
    assert data["passed"] is False and data["verdict"] == "ERRORED"
    assert data["banner"].startswith("ERRORED runs: 2 of 60 runs raised errors (run ids 7, 23)")
    assert data["completeness"]["complete"] is True and data["completeness"]["errored_run_ids"] == [7, 23]
    keys = {"campaign", "counts", "success", "columns", "requirements", "worst_cases", "sensitivity", "failure_reasons"}
    assert set(data) >= keys
    worst = data["worst_cases"]["fuel_remaining"]["runs"]
    assert [w["fuel_remaining"] for w in worst] == sorted(
        [r["fuel_remaining"] for r in synthetic[1] if r["status"] == "ok"]
    )[:5]
    assert worst[0]["command"] == f"refexmc rerun {out} {worst[0]['run_id']}"
    assert [r["run_id"] for r in data["worst_cases"]["errored"]["runs"]] == [7, 23]
    assert [r["run_id"] for r in data["worst_cases"]["unsuccessful"]["runs"]] == [3, 11, 40]


def test_sensitivity_matches_scipy_spearman(synthetic):
    """Sensitivity of the requirements' metrics (here fuel_remaining, failing: first)."""
    _, rows, report = synthetic
    section = report["summary"]["sensitivity"]
    assert section["targets"][0] == "fuel_remaining"
    remaining = ok_values(rows, "fuel_remaining")
    top = section["fuel_remaining"][0]
    assert top["parameter"] == "p.rcs.isp_s"  # the parameter that drives the propellant
    expected = sps.spearmanr(ok_values(rows, "p.rcs.isp_s"), remaining)
    assert top["rho"] == pytest.approx(expected.statistic, abs=1e-12)
    assert top["p_value"] == pytest.approx(expected.pvalue, rel=1e-9)


def residual_rank_correlation(inputs, output, j):
    """PRCC the slow way: regress rank(x_j) and rank(y) on the other inputs' ranks, correlate the residuals."""
    ranks = sps.rankdata(inputs, axis=0)
    others = np.column_stack([np.ones(len(output)), np.delete(ranks, j, axis=1)])
    ry = sps.rankdata(output)
    ex = ranks[:, j] - others @ np.linalg.lstsq(others, ranks[:, j], rcond=None)[0]
    ey = ry - others @ np.linalg.lstsq(others, ry, rcond=None)[0]
    return float(np.corrcoef(ex, ey)[0, 1])


def test_partial_rank_correlation_matches_residual_regression(synthetic):
    _, rows, report = synthetic
    parameters = ["p.rcs.isp_s", "p.navigation.rate_noise_deg_s"]
    inputs = np.column_stack([ok_values(rows, p) for p in parameters])
    output = ok_values(rows, "fuel_remaining")
    by_parameter = {r["parameter"]: r for r in report["summary"]["sensitivity"]["fuel_remaining"]}
    for j, parameter in enumerate(parameters):
        # the inverse-correlation identity and two least-squares fits agree to round-off
        assert by_parameter[parameter]["prcc"] == pytest.approx(residual_rank_correlation(inputs, output, j), abs=1e-9)
    assert by_parameter["p.rcs.isp_s"]["prcc"] < -0.9  # fuel_remaining = 0.5 - 0.3 (drive - 1) + small noise


def test_partial_rank_correlation_not_computable_with_too_few_runs():
    rng = np.random.default_rng(3)
    inputs = rng.normal(size=(6, 4))  # n < k + 3: no residual degrees of freedom
    rho, p = stats.partial_rank_correlation(inputs, rng.normal(size=6))
    assert np.isnan(rho).all() and np.isnan(p).all()
    inputs = rng.normal(size=(300, 3))
    output = inputs[:, 0] + 0.2 * rng.normal(size=300)
    rho, p = stats.partial_rank_correlation(inputs, output)
    assert rho[0] > 0.9 and p[0] < 1e-50 and abs(rho[2]) < 0.2


def test_html_is_self_contained(synthetic):
    out, _, report = synthetic
    page = (out / "report" / "index.html").read_text()
    assert not re.search(r"https?://", page), "the page must not reference the network"
    sources = re.findall(r"<img[^>]*\ssrc=\"([^\"]*)\"", page)
    assert len(sources) == page.count("<img") >= 4  # modes, propellant, sensitivity, convergence
    for src in sources:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1]).startswith(PNG_MAGIC)
    assert not re.search(r"<(script|link|iframe)\b", page)
    assert "refexmc rerun" in page and "FAIL" in page
    assert report["summary"]["figures"][0] == "The requirements' metrics"
    assert "Angle and rate errors per mode (000 Fig. 11 analogue)" in report["summary"]["figures"]


def test_mode_envelopes_align_runs_at_mode_start(synthetic):
    from refexmc.report import aggregate, data

    out, _, _ = synthetic
    result = aggregate.aggregate_histories(data.load(out))
    binned, q = result["modes"]["theta_t_deg"]
    sam = list(REFEX_MODES).index("SAM")
    # every run has theta = 100 exp(-tau): aligned at mode start, all percentiles coincide
    for b in range(0, 8):
        tau = (b + 0.5) * binned.dt
        lo, hi = 100 * np.exp(-(tau + 0.5 * binned.dt)), 100 * np.exp(-(tau - 0.5 * binned.dt))
        ratio = 10 ** (1 / 80)
        assert lo / ratio <= q[sam, b, 0] and q[sam, b, 4] <= hi * ratio
    assert result["nominal"] is not None and (np.diff(result["nominal"]["t_s"]) > 0).all()
    assert result["rows"] == sum(len(synthetic_history(r)) for r in synthetic[1] if r["status"] == "ok")
    # the controlled modes, RDM1 ... GEEM, as 000 Fig. 11: not NCM (no angle error, no valve)
    assert result["mode_names"] == list(REFEX_MODES)
    assert result["valve_samples"][0] == 0 and (result["valve_samples"][1:] > 0).all()
    assert [result["mode_names"][m] for m in aggregate.plotted_modes(result)] == list(REFEX_MODES)[1:]
    # the figure: a panel per mode with samples of the quantity; no angle panel where there is no angle error
    shown, left_out = aggregate.modes_with_samples(result, len(data.load(out).ok))
    names = result["mode_names"]
    assert [names[m] for m in shown["theta_t_deg"]] == [m for m in REFEX_MODES if m not in REFEX_WITHOUT_ANGLE_ERROR]
    assert [names[m] for m in shown["omega_m_deg_s"]] == list(REFEX_MODES)  # the rates are measured in NCM too
    assert left_out == {"theta_t_deg": {}, "omega_m_deg_s": {}}


OTHER_MODES = {"detumble": 20.0, "slew": 45.0, "hold": 90.0}  # another vehicle: names of its own, 3 modes
REFEX_WORDS = re.compile(r"\b(" + "|".join([*REFEX_MODES, *MODE_COLUMNS]) + r")\b")


def without_images(page):
    return re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]*", "", page)


def figure_titles(monkeypatch):
    """Record the axes titles of every figure the report renders: {figure number: [titles]}."""
    from refexmc.report import figures

    titles = []
    render = figures.png

    def recording(figure):
        titles.append([ax.get_title() for ax in figure.axes if ax.get_title()])
        return render(figure)

    monkeypatch.setattr(figures, "png", recording)
    return titles


def test_report_of_a_vehicle_with_three_modes_of_its_own_names(tmp_path, monkeypatch):
    rows = synthetic_runs(n=30, errored=(4,), failed=(9,), modes=OTHER_MODES)
    # detumble damps the rates: valves open, no angle error; slew and hold steer the attitude
    out = write_out(tmp_path / "out", rows, modes=OTHER_MODES, without_angle_error=("detumble",), vehicle="cubesat")
    titles = figure_titles(monkeypatch)
    report = make_report(out, require=["t_slew_s.max <= 100", "t_hold_s.p50 <= 95"], html=True)
    summary = report["summary"]
    assert summary["modes"] == ["detumble", "slew", "hold"]
    for name in OTHER_MODES:
        column = summary["columns"][f"t_{name}_s"]
        assert column["median"] == pytest.approx(np.median(successful_values(rows, f"t_{name}_s")))
        assert column["tail"] == "upper"
    assert [v["metric"] for v in report["requirements"]] == ["t_slew_s.max", "t_hold_s.p50"]
    assert "time in mode [s], median/max: detumble " in report["text"]
    assert ", slew " in report["text"] and ", hold " in report["text"]
    page = without_images((out / "report" / "index.html").read_text())
    assert "Modes: detumble → slew → hold." in page
    assert (out / "report" / "figures" / "modes.png").read_bytes().startswith(PNG_MAGIC)
    assert "Angle and rate errors per mode" in summary["figures"]  # no 000 figure number: not ReFEx
    assert ["slew", "hold", "detumble", "slew", "hold"] in titles  # the modes figure: angle row, rate row
    written = (out / "report" / "summary.json").read_text()
    for where, text in (("text", report["text"]), ("summary.json", written), ("index.html", page)):
        assert not REFEX_WORDS.search(text), f"{where} names a ReFEx mode: {REFEX_WORDS.search(text).group()}"


def test_output_without_modes_in_its_manifest_takes_them_from_the_runs_table(tmp_path, monkeypatch):
    """An output written before manifest.json listed its modes: the t_<mode>_s columns, upper-cased;
    the histories' lower-case names still find their mode. A mode that coasts is not plotted."""
    rows = synthetic_runs(n=12, errored=(), failed=(), modes=OTHER_MODES)
    coast = ("detumble",)
    out = write_out(tmp_path / "out", rows, modes=OTHER_MODES, without_angle_error=coast, coasting=coast, parts=1)
    storage.write_manifest(out, {"name": "synthetic", "status": "complete"})
    titles = figure_titles(monkeypatch)
    report = make_report(out, html=True)
    assert report["summary"]["modes"] == ["DETUMBLE", "SLEW", "HOLD"]
    assert ["SLEW", "HOLD", "DETUMBLE", "SLEW", "HOLD"] in titles  # the modes figure: angle (not coasting), rates
    assert "time in mode [s], median/max: DETUMBLE " in report["text"]


def test_mode_names_from_the_manifest_or_the_runs_columns():
    from refexmc.report import data

    columns = ["run_id", "t_end_s", "t_ncm_s", "t_rdm1_s", "fuel_remaining", "t_geem_s", "pulses_1"]
    assert data.mode_names({"modes": ["Detumble", "slew"]}, columns) == ["Detumble", "slew"]
    assert data.mode_names({}, columns) == ["NCM", "RDM1", "GEEM"]  # table order, t_end_s is the flight
    assert data.mode_names({"name": "old"}, ["t_end_s"]) == []
    for bad in ([], "NCM", ["slew", "SLEW"], ["slew", ""], ["slew", 3], ["end"]):
        with pytest.raises(ConfigError, match="modes"):
            data.mode_names({"modes": bad}, columns, file="manifest.json")
    assert data.load(ROOT / "baselines" / "smoke").modes == list(REFEX_MODES)


def test_manifest_modes_without_their_time_columns_are_bad_input(tmp_path):
    rows = synthetic_runs(n=6, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, histories=False, parts=1)
    storage.write_manifest(out, {"name": "synthetic", "status": "complete", "modes": [*REFEX_MODES, "LAND"]})
    with pytest.raises(ConfigError, match="lacks the time of modes listed in manifest.json: t_land_s") as info:
        make_report(out)
    assert info.value.file == out / "manifest.json"
    assert not (out / "report").exists()


def test_history_modes_match_by_name_without_regard_to_case():
    from refexmc.report import data

    names = pa.array(["hold", "SLEW", "coast", "Detumble", "hold"])
    expected = [2, 1, -1, 0, 2]  # coast: not a mode of the campaign
    assert data.mode_codes(names, ["DETUMBLE", "SLEW", "HOLD"]).tolist() == expected
    assert data.mode_codes(names.dictionary_encode(), ["detumble", "slew", "hold"]).tolist() == expected


def test_requirement_parser_good_and_bad():
    columns = ["run_id", "fuel_remaining", "attitude_error_end_deg", "p.rcs.thrust_scale.1", "t_sam_s"]
    good = parse_requirement(" fuel_remaining.p0.135 >= 0.2 ", columns)
    assert (good.metric, good.op, good.value) == ("fuel_remaining.p0.135", ">=", 0.2)
    assert parse_requirement("p.rcs.thrust_scale.1.p50<1.1", columns).metric == "p.rcs.thrust_scale.1.p50"
    assert parse_requirement("success_rate_lower95 > 0.9", columns).op == ">"
    assert parse_requirement("fuel_remaining.p1_lower95 >= 0.3", columns).value == 0.3
    assert parse_requirement("t_sam_s.mean_plus_3sd <= 1e2", columns).value == 100.0
    assert parse_requirement("t_sam_s.three_sigma <= 5", columns).metric == "t_sam_s.three_sigma"
    with pytest.raises(ConfigError, match="did you mean 'fuel_remaining.min'"):
        parse_requirement("fuel_remaning.min >= 0.2", columns)
    with pytest.raises(ConfigError, match="did you mean 'success_rate'"):
        parse_requirement("sucess_rate >= 1", columns)
    with pytest.raises(ConfigError, match="unknown statistic 'minn'.*did you mean 'fuel_remaining.min'"):
        parse_requirement("fuel_remaining.minn >= 0.2", columns)
    with pytest.raises(ConfigError, match="unknown metric 'run_id.max'"):
        parse_requirement("run_id.max < 5", columns)
    with pytest.raises(ConfigError, match="unknown operator '=>'"):
        parse_requirement("fuel_remaining.min => 0.2", columns)
    with pytest.raises(ConfigError, match="expected a number after '>=', got 'twenty'"):
        parse_requirement("fuel_remaining.min >= twenty", columns)
    with pytest.raises(ConfigError, match="expected 'METRIC OP VALUE'"):
        parse_requirement("fuel_remaining.min", columns)
    with pytest.raises(ConfigError, match="finite"):
        parse_requirement("fuel_remaining.min >= nan", columns)


def test_bad_requirement_in_campaign_file_names_file_and_line_and_writes_nothing(tmp_path):
    rows = synthetic_runs(n=12, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, requirements=["success_rate >= 1", "fuel_left.min >= 0.2"], histories=False)
    with pytest.raises(ConfigError) as info:
        make_report(out)
    message = str(info.value)
    assert "campaign.resolved.yaml:" in message and "requirements.1" in message and "fuel_left.min" in message
    assert info.value.line is not None
    assert not (out / "report").exists()
    out = write_out(tmp_path / "good", rows, requirements=["success_rate >= 1"], histories=False)
    with pytest.raises(ConfigError, match="did you mean 'pulses_total.max'"):
        make_report(out, require=["pulses_totl.max < 1000"])
    assert not (out / "report").exists()
    with pytest.raises(ConfigError, match="no campaign.resolved.yaml"):
        make_report(tmp_path)


def test_all_runs_succeeding_gives_the_no_failure_bound_and_passes(tmp_path):
    rows = synthetic_runs(n=40, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, requirements=["success_rate >= 1.0"], histories=False, parts=1)
    report = make_report(out, require=["failure_rate_upper95 <= 0.08", "fuel_remaining.count == 40"], html=False)
    assert report["passed"] is True
    success = report["summary"]["success"]
    assert success["lower95"] == pytest.approx(0.05 ** (1 / 40))
    assert "no failure in 40 runs" in success["statement"]
    assert not (out / "report" / "index.html").exists()
    assert (out / "report" / "summary.json").is_file()


def test_failure_sweep_sets_and_matrix(tmp_path):
    singles = [str(t) for t in range(1, 9)]
    pairs = [f"{a},{b}" for a in range(1, 9) for b in range(a + 1, 9)]
    sets = ["", *singles, *pairs]
    failed = {i for i, s in enumerate(sets) if "5" in s.split(",") or "6" in s.split(",")}
    rows = synthetic_runs(n=len(sets), errored=(), failed=failed, sets=sets)
    out = write_out(tmp_path / "out", rows, histories=False, parts=1)
    report = make_report(out, html=True)
    by_set = {s["failed_thrusters"]: s for s in report["summary"]["failure_sets"]}
    assert len(by_set) == 37
    assert by_set["5"]["success_rate"] == 0 and by_set["1,2"]["success_rate"] == 1
    assert by_set["5,6"]["failure_reasons"] == ["sam_timeout"]
    assert [s["size"] for s in report["summary"]["failure_sets"]][:3] == [0, 1, 1]
    # synthetic: every set without a yaw thruster (5, 6) succeeds; 000 Table 4 also rules out 6 pairs
    table4 = report["summary"]["failure_sets_vs_000_table4"]
    assert table4["compared"] == 36
    assert table4["disagree"] == ["1,4", "1,7", "2,3", "2,7", "3,8", "4,8"]
    assert "against 000 Table 4: 30 of 36" in report["text"]
    figures = report["summary"]["figures"]
    assert any("failure matrix" in title for title in figures)
    assert (out / "report" / "figures" / "failure_matrix.png").read_bytes().startswith(PNG_MAGIC)


def test_incomplete_campaign_without_nominal_run(tmp_path):
    rows = synthetic_runs(n=30, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, nominal_first=False, parts=1)
    text = (out / "campaign.resolved.yaml").read_text().replace("runs: 30", "runs: 50")
    (out / "campaign.resolved.yaml").write_text(text)
    report = make_report(out, require=["success_rate >= 1"], html=True)
    summary = report["summary"]
    assert report["verdict"] == "INCOMPLETE" and report["passed"] is False
    assert summary["completeness"]["missing_run_count"] == 20
    assert summary["completeness"]["missing_run_ids"] == "30-49"
    assert summary["banner"].startswith("INCOMPLETE campaign: 30 of 50 planned runs stored; 20 of 50 planned runs")
    assert "missing run ids 30-49" in summary["banner"]
    assert report["text"].splitlines()[0] == f"*** {summary['banner']} ***"
    assert "met   success_rate >= 1" in report["text"]  # holds on the stored runs; still no PASS
    assert summary["nominal"] is None
    assert "no failure in 30 runs" in summary["success"]["statement"]
    assert "PASS" not in report["text"]


def test_requirement_that_cannot_be_computed_fails(tmp_path):
    rows = synthetic_runs(n=10, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, histories=False, parts=1)
    report = make_report(out, require=["fuel_remaining.p0.135_lower95 >= 0.1"], html=False)
    verdict = report["requirements"][0]
    assert verdict["passed"] is False and verdict["actual"] is None and "not computable" in verdict["note"]


@pytest.mark.slow
def test_report_on_flown_campaign(tmp_path):
    """End to end on real flights: a small dispersed smoke campaign, stored as `run` stores it."""
    from stored import store_campaign

    from refexmc.config.load import load_campaign

    source = tmp_path / "campaign.yaml"
    text = (ROOT / "campaigns/smoke.yaml").read_text()
    text = text.replace("../configs/", f"{ROOT}/configs/").replace("runs: 20", "runs: 8")
    source.write_text(text)
    campaign = load_campaign(source)
    out = tmp_path / "out"
    rows = store_campaign(campaign, out)
    report = make_report(out, require=["fuel_remaining.min >= 0.05"])
    assert report["summary"]["counts"]["runs"] == 8
    assert report["summary"]["nominal"]["run_id"] == 0
    fuel = np.array([r["fuel_remaining"] for r in rows if r["status"] == "ok" and r["success"]])
    assert report["summary"]["columns"]["fuel_remaining"]["min"] == fuel.min()
    assert "Angle and rate errors per mode (000 Fig. 11 analogue)" in report["summary"]["figures"]


def test_failure_reason_table_counts_and_examples(tmp_path):
    failed = (2, 4, 5, 9, 12, 15, 17, 21, 30)
    rows = synthetic_runs(n=40, errored=(6, 33), failed=failed)
    for i in (2, 4, 5, 9, 12, 15, 17):
        rows[i]["failure_reason"] = "sam_timeout"
    rows[21]["failure_reason"] = "rdm1_timeout"
    rows[30]["failure_reason"] = None
    rows[33]["failure_reason"] = (
        "TimeoutError: run 33 exceeded the run time limit\nTraceback (most recent call last): ..."
    )
    out = write_out(tmp_path / "out", rows, histories=False, parts=1)
    report = make_report(out, html=True)
    reasons = report["summary"]["failure_reasons"]
    assert [(r["kind"], r["reason"], r["count"], r["example_run_ids"]) for r in reasons] == [
        ("failed flight", "sam_timeout", 7, [2, 4, 5, 9, 12]),  # the first 5 of 7
        ("failed flight", "(no reason recorded)", 1, [30]),
        ("failed flight", "rdm1_timeout", 1, [21]),
        ("errored run", "RuntimeError: boom", 1, [6]),
        ("errored run", "TimeoutError: run 33 exceeded the run time limit", 1, [33]),
    ]
    assert sum(r["count"] for r in reasons) == len(failed) + 2
    lines = report["text"].splitlines()
    table = lines[lines.index("failure reasons:") + 1 :]
    assert table[0].split() == ["failed", "flight", "sam_timeout", "7", "runs", "2,", "4,", "5,", "9,", "12,", "..."]
    assert table[4].split()[:3] == ["errored", "run", "TimeoutError:"]
    page = (out / "report" / "index.html").read_text()
    section = page.split("<h2>Failure reasons</h2>", 1)[1].split("<h2>", 1)[0]
    assert "sam_timeout" in section and "2, 4, 5, 9, 12, ..." in section and "Traceback" not in section
    assert report["verdict"] == "ERRORED"


def test_errored_runs_fail_min_but_a_percentile_holds_them_in_its_tail(tmp_path):
    """One errored run of 200: p1 (h = 199 * 0.01 = 1.99) stays between successful flights; of 100 it does not."""
    rows = synthetic_runs(n=200, errored=(17,), failed=())
    out = write_out(tmp_path / "out", rows, histories=False, parts=1)
    require = ["fuel_remaining.p1 >= 0.2", "fuel_remaining.min >= 0.2", "t_end_s.p99 <= 1000"]
    report = make_report(out, require=require, html=True)
    fuel = successful_values(rows, "fuel_remaining")
    assert [v["passed"] for v in report["requirements"]] == [True, False, True]
    # reference: the errored run at a far finite value, numpy's percentile
    assert report["requirements"][0]["actual"] == pytest.approx(np.percentile(np.append(fuel, -1e12), 1), rel=1e-12)
    assert "1 failing run ranked at the low end" in report["requirements"][0]["note"]
    assert report["requirements"][1]["note"] == "fails because of the errored run 17"
    assert report["verdict"] == "ERRORED" and report["passed"] is False
    assert "met   fuel_remaining.p1 >= 0.2" in report["text"]
    page = (out / "report" / "index.html").read_text()
    assert "PASS" not in re.sub(r"data:image/png;base64,[A-Za-z0-9+/=]*", "", page)
    assert 'class="banner">ERRORED runs: 1 of 200 runs raised errors (run ids 17)' in page
    rows = synthetic_runs(n=100, errored=(17,), failed=())
    out = write_out(tmp_path / "hundred", rows, histories=False, parts=1)
    verdict = make_report(out, require=require[:1], html=False)["requirements"][0]
    assert verdict["passed"] is False and verdict["actual"] is None  # h = 0.99: interpolates to the errored run


def test_all_runs_fine_but_manifest_running_or_a_chunk_missing_is_incomplete(tmp_path):
    rows = synthetic_runs(n=30, errored=(), failed=())
    out = write_out(tmp_path / "out", rows, requirements=["success_rate >= 1"], parts=3)
    assert make_report(out, html=False)["verdict"] == "PASS"  # the control: complete, every requirement met
    storage.write_manifest(out, {"name": "synthetic", "status": "running", "chunk_size": 10})
    report = make_report(out, html=False)
    assert report["verdict"] == "INCOMPLETE" and report["passed"] is False
    assert report["summary"]["completeness"]["problems"] == ["manifest status is 'running', not 'complete'"]
    storage.write_manifest(out, {"name": "synthetic", "status": "complete", "chunk_size": 10})
    (out / "histories" / storage.part_name(1)).unlink()
    completeness = make_report(out, html=False)["summary"]["completeness"]
    assert completeness["missing_chunks"] == [storage.part_name(1)] and not completeness["complete"]
    storage.write_manifest(out, {"name": "synthetic", "status": "complete", "chunk_size": 5})  # 6 chunks planned
    completeness = make_report(out, html=False)["summary"]["completeness"]
    assert completeness["missing_chunks"] == [storage.part_name(k) for k in (1, 3, 4, 5)]


def test_docs_list_every_tail_rule():
    from refexmc.report.tails import TAIL_RULES, worse_tail

    doc = (ROOT / "docs" / "report.md").read_text()
    for pattern, tail, meaning in TAIL_RULES:
        assert f"| `{pattern}` | {tail} | {meaning} |" in doc, f"docs/report.md lacks the tail rule of {pattern}"
    assert [worse_tail(c) for c in ("t_end_s", "t_geem_s", "pulses_total", "fuel_remaining", "p.rcs.isp_s")] == [
        "upper",
        "upper",
        "upper",
        "lower",
        None,
    ]


def test_rows_get_the_digits_that_show_their_spread():
    """SPORE's entry flight-path angle varies by 1e-6 deg about -5: 4 digits would print every statistic as -5."""
    from refexmc.report.text import number, row_digits

    narrow = {"std": 1.42e-6, "median": -5.0000026}
    digits = row_digits(narrow)
    assert number(-5.0000043, 4) == number(-4.9999975, 4) == "-5"
    assert number(-5.0000043, digits) != number(-4.9999975, digits)
    assert row_digits({"std": 0.1, "median": 0.5}) == 4  # a spread the 4 digits show already
    assert row_digits({"std": 0.0, "median": 3.0}) == 4 and row_digits({"std": None, "median": 1.0}) == 4
    assert row_digits({"std": 1e-300, "median": 1e10}) == 10  # capped


def test_scatter_draws_every_run_or_a_spread_and_the_worst():
    from refexmc.report import scatter_runs

    values = np.arange(20_000, dtype=float)[::-1].copy()  # run 0 has the largest value
    values[7] = np.nan
    assert (scatter_runs(values[:300], "upper") == np.arange(300)).all()
    shown = scatter_runs(values, "upper", limit=1000, worst=10)
    assert {0, 1, 2, 3, 4, 5, 6, 8, 9, 10} <= set(shown.tolist())  # the 10 largest (run 7 has no value)
    assert 7 not in shown
    assert 1000 <= len(shown) <= 1010 and (np.diff(shown) > 0).all()
    lower = scatter_runs(values, "lower", limit=1000, worst=10)
    assert set(range(19_990, 20_000)) <= set(lower.tolist())


def test_a_campaign_whose_drivers_are_only_failure_sets_reports_without_a_scatter_figure(tmp_path):
    """An enumeration of failure sets without dispersed inputs: the sensitivity ranks the sets (a
    discrete cause, no axis of values), and the scatter of inputs has no panel; it used to raise
    'max() arg is an empty sequence' and write no report."""
    sets = {i: ("", "1", "2")[i % 3] for i in range(60)}
    rows = synthetic_runs(sets=sets, errored=())
    for i, row in enumerate(rows):
        del row["p.rcs.isp_s"], row["p.navigation.rate_noise_deg_s"]
        row["fuel_used_kg"] = 1.0 + (0.5 if row["failed_thrusters"] == "1" else 0.0) + 0.001 * i
    out = write_out(tmp_path / "out", rows, requirements=["fuel_used_kg.max <= 1.2"], histories=False)
    summary = make_report(out)
    assert summary["verdict"] == "FAIL"
    html = (out / "report" / "index.html").read_text()
    assert "What drives the failing" in html and "Top inputs against" not in html


def test_a_pointing_record_bounds_its_column_in_the_figures():
    from refexmc.report import bounds_of

    summary = {
        "requirements": [
            {"metric": "pointing_ape_max_arcsec", "kind": "pointing", "value": 2.0, "requirement": "APE <= 2 arcsec"},
            {"metric": "fuel_used_kg.max", "value": 1.0, "requirement": "fuel_used_kg.max <= 1"},
            {"metric": "success_rate", "value": 0.99, "requirement": "success_rate >= 0.99"},
        ]
    }
    assert bounds_of("pointing_ape_max_arcsec", summary) == [(2.0, "required: APE <= 2 arcsec")]
    assert bounds_of("fuel_used_kg", summary) == [(1.0, "required: fuel_used_kg.max <= 1")]
    assert bounds_of("success_rate", summary) == []


def test_a_worst_case_is_printed_with_the_digits_of_its_statistics_row(tmp_path):
    """A flight time spread over micro-seconds: 4 significant digits printed the worst run as '100',
    like every other run (SPORE's entry angle read '-5'); it gets the digits its row shows."""
    rows = synthetic_runs(errored=())
    for i, row in enumerate(rows):
        row["t_end_s"] = 100.0 + 1e-6 * i
    out = write_out(tmp_path / "out", rows, histories=False)
    text = make_report(out, html=False)["text"]
    line = next(s for s in text.splitlines() if s.startswith("largest t_end_s"))
    assert "(100.000059)" in line, line
