"""The shipped ReFEx campaigns against 000's published results, flown in-process.

- refex-mc100 (000 sec. 6.2, Fig. 12): every dispersed flight succeeds and keeps at least 20 % of
  its propellant; 000 says "most" runs use more than the nominal one: the share is measured here
  and recorded in docs/model.md, not asserted beyond "more than half".
- failure-sweep (000 sec. 5, Table 4): exactly the compensable single and double failures complete.
"""

import sys
from pathlib import Path

import pytest

from refexmc.campaign.chunk import fly_chunk
from refexmc.config.load import load_campaign

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))
from gen_failure_sweep import TABLE_4, completes, failed_set  # noqa: E402


@pytest.fixture(scope="module")
def mc100():
    campaign = load_campaign(ROOT / "campaigns" / "refex-mc100.yaml")
    rows, _ = fly_chunk(campaign, range(campaign["runs"]))
    return campaign, rows


def test_mc100_every_flight_succeeds_with_a_fifth_of_its_propellant(mc100):
    """000 sec. 6.2 and 7: no run failed, and every run kept more than roughly 20 %."""
    campaign, rows = mc100
    assert len(rows) == campaign["runs"] == 100
    assert all(row["status"] == "ok" and row["success"] for row in rows), [r["failure_reason"] for r in rows]
    assert min(row["fuel_remaining"] for row in rows) >= 0.20


def test_mc100_most_dispersed_runs_use_more_than_the_nominal(mc100):
    """000 sec. 6.2 / Fig. 12: "most of the simulations consume more fuel than the nominal case"."""
    _, rows = mc100
    nominal = next(row for row in rows if row["run_id"] == 0)
    dispersed = [row for row in rows if row["run_id"] != 0]
    more = sum(row["fuel_used_kg"] > nominal["fuel_used_kg"] for row in dispersed)
    assert more > len(dispersed) / 2, f"{more} of {len(dispersed)}"


def test_failure_sweep_agrees_with_table_4():
    """000 Table 4: the 15 compensable sets complete, the 21 others do not (36 of 36)."""
    campaign = load_campaign(ROOT / "campaigns" / "failure-sweep.yaml")
    rows, _ = fly_chunk(campaign, range(campaign["runs"]))
    outcome = {failed_set(row): completes(row) for row in rows}
    assert outcome.pop(()) is True  # the nominal run
    assert len(outcome) == 36
    disagree = sorted(s for s, done in outcome.items() if done != (s in TABLE_4))
    assert disagree == []
