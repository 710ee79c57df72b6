"""Sweeps and `--until-decided` on the Dask backend fly the same runs as on loky."""

import pandas as pd
import pytest

distributed = pytest.importorskip("distributed")
from stored import campaign_copy, invoke_run, read_runs  # noqa: E402

from refexmc.campaign import run as run_module  # noqa: E402

SWEEP = "sweep:\n  axes:\n    - parameter: rcs.propellant_kg\n      values: [0.42, 0.76]\n"
WITHOUT_PROPELLANT = ("  rcs.propellant_kg: {dist: truncnorm, sigma: 0.0253, low: 0.57, high: 0.95}\n", "")


@pytest.mark.slow
def test_a_sweep_and_a_stopped_campaign_on_dask_equal_loky(tmp_path, monkeypatch):
    monkeypatch.setenv(run_module.CHUNK_SIZE_ENV, "3")
    sweep = campaign_copy("refex-mc100.yaml", tmp_path, "sweep.yaml", [WITHOUT_PROPELLANT, ("runs: 100", "runs: 6")])
    sweep.write_text(sweep.read_text() + SWEEP)
    for backend in (["-j", "1"], ["--backend", "dask", "--scheduler", "local:1"]):
        out = tmp_path / f"sweep-{backend[-1]}"
        result = invoke_run(sweep, "-o", out, "--no-progress", *backend)
        assert result.exit_code == 0, result.output
    for k in (0, 1):
        folder = f"points/{k:03d}"
        pd.testing.assert_frame_equal(
            read_runs(tmp_path / "sweep-1" / folder), read_runs(tmp_path / "sweep-local:1" / folder)
        )

    decided = campaign_copy(
        "refex-mc100.yaml",
        tmp_path,
        "decided.yaml",
        [("  - fuel_remaining.min >= 0.20", "  - success_rate_lower95 >= 0.5"), ("  - success_rate >= 1.0", "")],
    )
    options = ["--until-decided", "--batch", "6", "--runs", "60", "--no-progress"]
    loky = invoke_run(decided, "-o", tmp_path / "decided-loky", "-j", "1", *options)
    dask = invoke_run(decided, "-o", tmp_path / "decided-dask", "--backend", "dask", "--scheduler", "local:1", *options)
    assert loky.exit_code == dask.exit_code == 0, (loky.output, dask.output)
    # every run succeeds: the lower bound of 6 of 6 at the first look's alpha (0.0079) is 0.45 < 0.5,
    # of 12 of 12 at the second's (0.0068) 0.66
    assert "stopped when decided after 12 of 60 runs" in dask.output
    pd.testing.assert_frame_equal(read_runs(tmp_path / "decided-loky"), read_runs(tmp_path / "decided-dask"))
