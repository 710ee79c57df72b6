"""Published values beside ours: the campaign's ``published`` entries against the stored runs.

For each entry of ``OUT/campaign.resolved.yaml`` ``published`` (``refexmc.config.published``)
and each of its columns: the entry's statistic over the flown runs (status ok, finite values;
failed flights included, errored runs not), the number of runs it covers, the source's value and
the ratio source / ours (null when ours is 0 or not computable). The values come from the
campaign file only, never from the flight software.
"""

import math

import pandas as pd

from refexmc.config.published import check_published, statistic_meaning
from refexmc.report import stats


def numeric_columns(runs):
    """The runs table's numeric columns (not the flags and strings: status, success, reasons)."""
    return [
        c for c in runs.columns if pd.api.types.is_numeric_dtype(runs[c]) and not pd.api.types.is_bool_dtype(runs[c])
    ]


def load_published(campaign):
    """[Published] of the resolved campaign, checked against the stored runs table (ConfigError
    naming ``campaign.resolved.yaml``, its line and key path)."""
    entries = campaign.resolved.get("published") or []
    resolved = campaign.out / "campaign.resolved.yaml"
    return check_published(entries, numeric_columns(campaign.runs), file=resolved, lines=campaign.resolved_lines)


def ratio(published, ours):
    """published / ours; None when ours is 0 or either is not finite."""
    if ours is None or not math.isfinite(ours) or ours == 0.0 or not math.isfinite(published):
        return None
    return published / ours


def sections(campaign, entries):
    """One JSON-ready dict per published entry: source, statistic, what it covers, a row per column."""
    ok = campaign.ok
    errored = len(campaign.errored)
    result = []
    for entry in entries:
        rows = []
        for column, value in entry.values.items():
            values = ok[column].to_numpy(dtype=float)
            ours = stats.column_stat(values, entry.statistic)
            n = int(stats.column_stat(values, "count"))
            rows.append(
                {
                    "column": column,
                    "ours": ours if math.isfinite(ours) else None,
                    "n": n,
                    "published": float(value),
                    "ratio_published_to_ours": ratio(float(value), ours),
                }
            )
        covers = f"the {len(ok)} flown runs (status ok) with a value in the column"
        if errored:
            covers += f"; {errored} errored run{'s' if errored != 1 else ''} not included"
        result.append(
            {
                "source": entry.source,
                "statistic": entry.statistic,
                "statistic_meaning": statistic_meaning(entry.statistic),
                "covers": covers,
                "rows": rows,
            }
        )
    return result
