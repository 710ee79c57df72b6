"""Pointing requirements (issue 35, docs/pointing.md): the core's indices and interpretations
against closed forms, the config's bad input, and a flight's columns.

The closed forms are of a sinusoid plus a bias about one body axis, e(t) = b + A sin(w t), sampled
over whole periods at N points each: over a period the sampled phases are uniform, so

- APE, ensemble: b + A (a sample sits on the peak); temporal: the P_C quantile of b + A sin,
  b + A sin(pi (P_C - 1/2)) (P(sin <= s) = 1/2 + asin(s)/pi);
- MPE over whole periods: |b|; RPE over one-period intervals: ensemble A, temporal A sin(pi P_C / 2)
  (P(|sin| <= s) = 2 asin(s)/pi); PDE over half periods: the half-period means b +- 2A/pi differ by 4A/pi;
- mixed against a bound c: the fraction of time above it, 1/2 - asin((c - b)/A)/pi.

A sampled quantile or fraction differs from the continuous one by at most one sample's change,
2 pi A / N (the largest slope times the step), the tolerance below.
"""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from refexmc.config import pointing as config_pointing
from refexmc.core import layout as L
from refexmc.core import pointing, quaternion

N = 4000  # samples per period
PERIOD = 400.0  # s
DT = PERIOD / N
BIAS, AMPLITUDE = 3e-6, 1e-6  # rad: b > A, so |e| = e
SAMPLE_TOL = 2.0 * math.pi * AMPLITUDE / N  # one sample's change of the sinusoid


def row(index=L.POINTING_INDEX_ABSOLUTE, interpretation=L.INTERPRETATION_TEMPORAL, error=L.ERROR_TOTAL,
        axis=(1.0, 0.0, 0.0), p_c=0.9973, bound=0.0, delta_t=math.inf, knowledge=0.0, modes=1,
        start=0.0, end=math.inf):  # fmt: skip
    r = np.zeros(L.POINTING_SIZE)
    r[L.P_INDEX] = index
    r[L.P_INTERPRETATION] = interpretation
    r[L.P_ERROR] = error
    r[L.P_AXIS : L.P_AXIS + 3] = axis
    r[L.P_PROBABILITY] = p_c
    r[L.P_BOUND] = bound
    r[L.P_DELTA_T] = delta_t
    r[L.P_KNOWLEDGE] = knowledge
    r[L.P_MODE_MASK] = modes
    r[L.P_WINDOW_FROM] = start
    r[L.P_WINDOW_TO] = end
    return r


def fly_errors(rows, errors, modes=None, dt=DT, knowledge_errors=None):
    """Record rotation vectors ``errors`` (steps, 3) as true-vs-reference errors (reference: identity)
    at t = k dt, mode ``modes[k]`` (0), measured attitude truth (x) rot(knowledge_errors[k]); reduce."""
    table = np.array(rows)
    rec = pointing.new_record(table, len(errors) + 2)
    q_ref = np.array([0.0, 0.0, 0.0, 1.0])
    q_true, q_meas, rot = np.empty(4), np.empty(4), np.empty(4)
    for k, e in enumerate(errors):
        quaternion.from_rotation_vector(e[0], e[1], e[2], q_true)
        q_meas[:] = q_true
        if knowledge_errors is not None:
            ke = knowledge_errors[k]
            quaternion.from_rotation_vector(ke[0], ke[1], ke[2], rot)
            quaternion.multiply(q_true, rot, q_meas)
        pointing.record(rec, q_true, q_ref, q_meas, True, 0 if modes is None else int(modes[k]), k * dt)
    values = np.empty(len(rows))
    pointing.reduce(rec, dt, values)
    return values


def sinusoid(periods=3, bias=BIAS, amplitude=AMPLITUDE, axis=0):
    t = np.arange(periods * N) * DT
    e = np.zeros((len(t), 3))
    e[:, axis] = bias + amplitude * np.sin(2.0 * math.pi * t / PERIOD)
    return e


def test_ape_of_a_sinusoid_plus_bias_matches_its_closed_form():
    p_c = 0.9973
    values = fly_errors(
        [row(interpretation=L.INTERPRETATION_ENSEMBLE), row(p_c=p_c), row(error=L.ERROR_AXIS)], sinusoid()
    )
    # the rotation vector of a rotation about x is recovered to ~1e-22 rad here (angle 4e-6 rad)
    assert values[0] == pytest.approx(BIAS + AMPLITUDE, abs=1e-18)
    assert values[1] == pytest.approx(BIAS + AMPLITUDE * math.sin(math.pi * (p_c - 0.5)), abs=SAMPLE_TOL)
    assert values[2] == pytest.approx(values[1], abs=1e-18)  # x axis: the whole error


def test_mpe_rpe_pde_of_a_sinusoid_plus_bias_match_their_closed_forms():
    p_c = 0.95
    rows = [
        row(index=L.POINTING_INDEX_MEAN, interpretation=L.INTERPRETATION_ENSEMBLE),
        row(index=L.POINTING_INDEX_MEAN, interpretation=L.INTERPRETATION_ENSEMBLE, delta_t=PERIOD),
        row(index=L.POINTING_INDEX_RELATIVE, interpretation=L.INTERPRETATION_ENSEMBLE, delta_t=PERIOD),
        row(index=L.POINTING_INDEX_RELATIVE, p_c=p_c, delta_t=PERIOD),
        row(index=L.POINTING_INDEX_DRIFT, interpretation=L.INTERPRETATION_ENSEMBLE, delta_t=PERIOD / 2),
    ]
    values = fly_errors(rows, sinusoid())
    # the mean of N uniformly phased samples of a sine is 0 to rounding: ~N ulp of A
    assert values[0] == pytest.approx(BIAS, abs=1e-18)
    assert values[1] == pytest.approx(BIAS, abs=1e-18)
    assert values[2] == pytest.approx(AMPLITUDE, abs=1e-18)
    assert values[3] == pytest.approx(AMPLITUDE * math.sin(math.pi * p_c / 2.0), abs=SAMPLE_TOL)
    # half-period means of N/2 samples: 2A/pi to O(1/N^2) (the midpoint rule on a sine)
    assert values[4] == pytest.approx(4.0 * AMPLITUDE / math.pi, rel=1e-5)


def test_pre_compares_the_means_of_observation_periods():
    """Two observation periods of mode 0 with different biases, mode 1 between them: PRE is the
    difference of their means; PDE within each period sees only its own intervals."""
    first = sinusoid(periods=2, bias=BIAS)
    gap = np.zeros((N, 3))
    second = sinusoid(periods=2, bias=BIAS + 2e-7)
    errors = np.vstack([first, gap, second])
    modes = np.r_[np.zeros(len(first)), np.ones(N), np.zeros(len(second))]
    rows = [
        row(index=L.POINTING_INDEX_REPRODUCIBILITY, interpretation=L.INTERPRETATION_ENSEMBLE),
        row(index=L.POINTING_INDEX_DRIFT, interpretation=L.INTERPRETATION_ENSEMBLE, delta_t=PERIOD),
    ]
    values = fly_errors(rows, errors, modes)
    assert values[0] == pytest.approx(2e-7, abs=1e-18)
    assert values[1] < 1e-18  # equal means of whole periods within a period


def test_mixed_is_the_fraction_of_window_time_above_the_bound():
    bound = BIAS + 0.5 * AMPLITUDE
    values = fly_errors([row(interpretation=L.INTERPRETATION_MIXED, bound=bound)], sinusoid())
    expected = 0.5 - math.asin((bound - BIAS) / AMPLITUDE) / math.pi  # 1/3
    assert values[0] == pytest.approx(expected, abs=1.0 / N)


def test_window_times_and_modes_select_the_samples():
    errors = np.zeros((100, 3))
    errors[:, 0] = np.arange(100) * 1e-8  # growing: the window's largest is its last sample
    modes = np.r_[np.zeros(50), np.ones(50)]
    rows = [
        row(interpretation=L.INTERPRETATION_ENSEMBLE, start=10 * DT, end=30 * DT),
        row(interpretation=L.INTERPRETATION_ENSEMBLE, modes=0b01),
        row(interpretation=L.INTERPRETATION_ENSEMBLE, modes=0b10, end=70 * DT),
        row(interpretation=L.INTERPRETATION_ENSEMBLE, modes=0b100),  # a mode never flown: no samples
    ]
    values = fly_errors(rows, errors, modes)
    assert values[0] == pytest.approx(30e-8, rel=1e-12)
    assert values[1] == pytest.approx(49e-8, rel=1e-12)
    assert values[2] == pytest.approx(70e-8, rel=1e-12)
    assert math.isnan(values[3])


def test_los_sees_no_rotation_about_the_boresight():
    errors = np.zeros((10, 3))
    errors[:, 0] = 5e-6  # about the boresight x: the line of sight does not move
    errors[:, 1] = np.linspace(0.0, 2e-6, 10)
    boresight = row(interpretation=L.INTERPRETATION_ENSEMBLE, error=L.ERROR_LOS, axis=(1.0, 0.0, 0.0))
    total = row(interpretation=L.INTERPRETATION_ENSEMBLE)
    values = fly_errors([boresight, total], errors)
    # rotating x by (5e-6, 2e-6, 0) rad moves it by 2e-6 rad to second order (5e-6 * 2e-6 = 1e-11)
    assert values[0] == pytest.approx(2e-6, rel=1e-5)
    assert values[1] == pytest.approx(math.hypot(5e-6, 2e-6), rel=1e-12)


def test_a_large_los_error_is_the_exact_angle():
    angle = 0.7  # rad about z: the boresight x moves by exactly this
    values = fly_errors(
        [row(interpretation=L.INTERPRETATION_ENSEMBLE, error=L.ERROR_LOS, axis=(1.0, 0.0, 0.0))],
        np.array([[0.0, 0.0, angle]]),
    )
    assert values[0] == pytest.approx(angle, rel=1e-14)


def test_knowledge_index_measures_estimated_minus_true():
    truth = sinusoid(periods=1)
    knowledge = np.zeros_like(truth)
    knowledge[:, 2] = np.linspace(-3e-7, 4e-7, len(truth))
    values = fly_errors(
        [row(interpretation=L.INTERPRETATION_ENSEMBLE, knowledge=1.0)], truth, knowledge_errors=knowledge
    )
    # the body-axes knowledge error is the rotation vector of conj(q) (x) q (x) rot(k) = rot(k)
    assert values[0] == pytest.approx(4e-7, rel=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.one_of(st.just(0.0), st.floats(1e-12, 1e-4)), min_size=1, max_size=60),
    st.floats(0.01, 0.9999),
)
def test_a_temporal_value_never_exceeds_the_largest_error(samples, p_c):
    errors = np.zeros((len(samples), 3))
    errors[:, 1] = samples
    values = fly_errors([row(p_c=p_c), row(interpretation=L.INTERPRETATION_ENSEMBLE)], errors)
    assert values[0] <= values[1]
    # and it is the smallest sample with at least P_C of the samples at or below it (the recorded
    # magnitudes come back through a quaternion: equal to the inputs to 1e-12 relative)
    magnitudes = np.abs(errors[:, 1])
    at_or_below = np.count_nonzero(magnitudes <= values[0] * (1 + 1e-12))
    below = np.count_nonzero(magnitudes < values[0] * (1 - 1e-12))
    assert at_or_below / len(samples) >= p_c - 1e-12
    assert below / len(samples) < p_c


def test_too_small_a_buffer_gives_nan_not_a_partial_statistic():
    rec = pointing.new_record(np.array([row(interpretation=L.INTERPRETATION_ENSEMBLE)]), 3)
    q = np.array([0.0, 0.0, 0.0, 1.0])
    for k in range(5):
        pointing.record(rec, q, q, q, True, 0, k * 1.0)
    values = np.empty(1)
    pointing.reduce(rec, 1.0, values)
    assert math.isnan(values[0])


def test_column_names_start_with_the_index():
    assert config_pointing.column_name("APE", "total", "temporal", "arcsec") == "ape_total_temporal_arcsec"
    assert config_pointing.column_name("AKE", "los", "mixed", "arcsec", "star") == "ake_los_mixed_star_fraction"


# --- a campaign with pointing requirements: runs columns, summary.json, report -----------------

POINTING_RECORDS = """  - index: APE
    error: total
    bound_deg: 2.0
    p_c: 0.9973
    interpretation: temporal
    window: {modes: [GEEM]}
  - index: APE
    error: total
    bound_deg: 2.0
    p_c: 0.9973
    interpretation: ensemble
    window: {modes: [GEEM]}
  - index: RPE
    error: los
    boresight: [1, 0, 0]
    bound_deg: 0.5
    p_c: 0.95
    interpretation: mixed
    window: {modes: [GEEM]}
    delta_t_s: 5.0
  - index: AKE
    error: x
    bound_deg: 1.0
    p_c: 0.9973
    interpretation: temporal
    window: {from_s: 10.0}
    runs: failure_free
  - ape_total_ensemble_deg.max <= 10.0
"""


def test_a_campaign_reports_each_pointing_requirement(tmp_path):
    import json

    import pyarrow.parquet as pq
    from click.testing import CliRunner
    from stored import campaign_copy

    from refexmc.cli import main

    path = campaign_copy("smoke.yaml", tmp_path, replace=[("runs: 20", "runs: 4")])
    path.write_text(path.read_text() + POINTING_RECORDS)
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    runs = pq.read_table(out / "runs").to_pandas()
    columns = ["ape_total_temporal_deg", "ape_total_ensemble_deg", "rpe_los_mixed_fraction", "ake_x_temporal_deg"]
    assert all(c in runs.columns for c in columns)
    assert (runs["ape_total_temporal_deg"] <= runs["ape_total_ensemble_deg"]).all()
    assert runs[columns].notna().all().all()
    report = CliRunner().invoke(main, ["report", str(out)])
    summary = json.loads((out / "report/summary.json").read_text())
    pointed = [r for r in summary["requirements"] if r.get("kind") == "pointing"]
    assert [r["metric"] for r in pointed] == columns
    for r in pointed:
        for key in ("index", "error", "interpretation", "p_c", "confidence", "window", "runs", "passed"):
            assert key in r, key
        assert r["worst_runs"] and r["worst_runs"][0]["command"].startswith("refexmc rerun")
    # 4 runs cannot show 99 % of runs (temporal) or P_C (ensemble) at 95 %: 299 and 1109 runs needed
    assert [r["runs_needed"] for r in pointed[:2]] == [299, 1109]
    assert not pointed[0]["passed"] and not pointed[1]["passed"]
    assert report.exit_code == 1  # a FAIL is a verdict, not bad input
    assert "pointing requirements" in report.output and "worst runs" in report.output
    # the 'METRIC OP VALUE' grammar reads the new columns too
    texts = [r["requirement"] for r in summary["requirements"] if r["passed"]]
    assert "ape_total_ensemble_deg.max <= 10.0" in texts


def test_runs_needed_with_none_outside():
    from refexmc.report.pointing import runs_needed

    assert runs_needed(0.9973, 0.95) == 1109  # ln 0.05 / ln 0.9973 = 1108.04
    assert runs_needed(0.99, 0.95) == 299
    assert 0.05 ** (1 / 1109) >= 0.9973 > 0.05 ** (1 / 1108)


def test_the_worked_example_of_docs_pointing():
    """docs/pointing.md: three runs e_i = b_i + A_i sin(2 pi t / T), T = 100 s at 10 Hz over four
    periods; each value against its closed form and the page's table, then the three verdicts."""
    from pathlib import Path
    from types import SimpleNamespace

    import pandas as pd

    from refexmc.report import pointing as report_pointing

    arcsec = math.pi / 180.0 / 3600.0
    dt, period, p_c, bound = 0.1, 100.0, 0.9973, 0.4
    toy = [(0.10, 0.20), (0.25, 0.10), (0.35, 0.10)]
    t = np.arange(4 * int(period / dt)) * dt
    rows = [
        row(p_c=p_c),
        row(interpretation=L.INTERPRETATION_ENSEMBLE),
        row(interpretation=L.INTERPRETATION_MIXED, bound=bound * arcsec),
        row(index=L.POINTING_INDEX_MEAN, interpretation=L.INTERPRETATION_ENSEMBLE),
        row(index=L.POINTING_INDEX_RELATIVE, interpretation=L.INTERPRETATION_ENSEMBLE, delta_t=period),
    ]
    values = []
    for b, a in toy:
        e = np.zeros((len(t), 3))
        e[:, 0] = (b + a * np.sin(2.0 * math.pi * t / period)) * arcsec
        v = fly_errors(rows, e, dt=dt)
        values.append([v[0] / arcsec, v[1] / arcsec, v[2], v[3] / arcsec, v[4] / arcsec])
        step = 2.0 * math.pi * a * dt / period  # one sample's change
        assert v[0] / arcsec == pytest.approx(b + a * math.sin(math.pi * (p_c - 0.5)), abs=step)
        assert v[1] / arcsec == pytest.approx(b + a, abs=1e-12)
        above = 0.0 if b + a <= bound else 0.5 - math.asin((bound - b) / a) / math.pi
        assert v[2] == pytest.approx(above, abs=1.0 / 1000)  # a fraction of 1000 samples per period
        assert v[3] / arcsec == pytest.approx(b, abs=1e-12)
        assert v[4] / arcsec == pytest.approx(a, abs=1e-12)
    page = (Path(__file__).resolve().parents[1] / "docs/pointing.md").read_text()
    for (b, a), v in zip(toy, values, strict=True):
        assert (
            f"| {b:.2f}, {a:.2f} | {v[0]:.5f} ({b + a * math.sin(math.pi * (p_c - 0.5)):.5f}) | {v[1]:.2f} |" in page
        ), v
    # the verdicts: a campaign of these three runs, every one failure-free
    runs = pd.DataFrame(
        {
            "run_id": [0, 1, 2],
            "status": ["ok"] * 3,
            "success": [True] * 3,
            "failed_thrusters": [""] * 3,
            "ape_total_temporal_arcsec": [v[0] for v in values],
            "ape_total_ensemble_arcsec": [v[1] for v in values],
            "ape_total_mixed_fraction": [v[2] for v in values],
        }
    )
    campaign = SimpleNamespace(runs=runs, out=Path("toy"))
    mission = {"modes": [{"name": "science"}], "navigation": {}}
    records = [
        {"index": "APE", "error": "total", "bound_arcsec": bound, "p_c": p_c, "interpretation": kind, "window": {}}
        for kind in ("temporal", "ensemble", "mixed")
    ]
    temporal, ensemble, mixed = (report_pointing.evaluate(r, campaign) for r in config_pointing.parse(records, mission))
    assert temporal["runs_within"] == ensemble["runs_within"] == 2
    assert temporal["actual"] == pytest.approx(0.13535, abs=1e-5) and not temporal["passed"]
    assert (temporal["runs_needed"], ensemble["runs_needed"]) == (299, 1109)
    assert ensemble["actual"] == temporal["actual"] and not ensemble["passed"]
    assert mixed["mean_fraction_above"] == pytest.approx(1 / 9, abs=1e-3)
    assert mixed["actual"] == pytest.approx(0.4356, abs=2e-3) and not mixed["passed"]
    for word in ("0.1354", "0.368", "0.4356", "1109", "299"):
        assert word in page


@pytest.mark.parametrize(("n", "passes"), [(20, False), (1108, False), (1109, True)])
def test_mixed_without_spread_is_bounded_without_the_t_distribution(n, passes):
    """Every run with no time above the bound: the t bound would be 0 from any number of runs (a
    PASS from 20 runs, before). The distribution-free bound instead: the mean fraction is at most
    the share of runs with any time above, whose upper Clopper-Pearson bound with none above is
    1 - (1 - confidence)^(1/n) (closed form): 1109 runs show 1 - P_C = 0.27 % at 95 %."""
    from pathlib import Path
    from types import SimpleNamespace

    import pandas as pd

    from refexmc.report import pointing as report_pointing

    runs = pd.DataFrame(
        {"run_id": range(n), "status": ["ok"] * n, "success": [True] * n, "failed_thrusters": [""] * n}
    ).assign(ape_total_mixed_fraction=0.0)
    campaign = SimpleNamespace(runs=runs, out=Path("toy"))
    mission = {"modes": [{"name": "science"}], "navigation": {}}
    record = {"index": "APE", "error": "total", "bound_arcsec": 5.0, "p_c": 0.9973, "interpretation": "mixed"}
    (req,) = config_pointing.parse([{**record, "window": {}}], mission)
    verdict = report_pointing.evaluate(req, campaign)
    assert verdict["actual"] == pytest.approx(1.0 - 0.05 ** (1.0 / n), rel=1e-9)
    assert verdict["passed"] is passes and verdict["runs_needed"] == 1109
    assert ("that needs 1109" in verdict["note"]) is (not passes)
