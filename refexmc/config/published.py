"""Values a source publishes for the same campaign: the campaign key ``published``.

Each entry names its ``source``, the ``statistic`` its numbers are (one of the requirement
grammar's, :mod:`refexmc.config.requirements`: ``three_sigma``, ``std``, ``mean``, ``p99``, ...)
and ``values``, a mapping runs column -> the source's value in the column's unit. ``refexmc
report`` computes the same statistic over the flown runs and shows it beside the source's, with
the ratio source / ours (``refexmc.report.published``). Example, 004 Table 2's ISS column::

    published:
      - source: "004 Table 2, ISS column (3-sigma entry state uncertainties)"
        statistic: three_sigma
        values: {entry_longitude_deg: 0.4993, entry_speed_m_s: 0.0379}

:func:`check_published` refuses (ConfigError with file, line and key path) a statistic the
grammar does not know and a column the campaign's runs table will not have; ``load_campaign``
checks against the columns the campaign declares, ``report`` again against the stored table.
"""

import difflib
from dataclasses import dataclass

from refexmc.config.errors import ConfigError
from refexmc.config.requirements import (
    DERIVED_COLUMNS,
    NOT_METRIC_COLUMNS,
    ORBIT_COLUMNS,
    POINTING_COLUMNS,
    SUGGESTED_STATS,
    WHEEL_COLUMNS,
    not_produced,
    parse_percentile_stat,
    valid_stat,
)

STATISTIC_MEANINGS = {
    "count": "number of runs with a value",
    "min": "minimum",
    "max": "maximum",
    "mean": "mean",
    "median": "median",
    "std": "sample standard deviation (ddof 1)",
    "three_sigma": "3 x sample standard deviation (ddof 1)",
    "mean_minus_3sd": "mean - 3 sd",
    "mean_plus_3sd": "mean + 3 sd",
    "tol_lower": "lower normal tolerance bound (99.865 % coverage, 95 % confidence)",
    "tol_upper": "upper normal tolerance bound (99.865 % coverage, 95 % confidence)",
}


@dataclass(frozen=True)
class Published:
    source: str
    statistic: str
    values: dict  # runs column -> the source's value


def statistic_meaning(stat):
    """What a statistic of the grammar is, in words (for the report)."""
    if stat in STATISTIC_MEANINGS:
        return STATISTIC_MEANINGS[stat]
    percent, bound = parse_percentile_stat(stat)
    text = f"{percent:g}th percentile"
    return text if bound is None else f"one-sided 95 % {bound} confidence bound of the {text}"


def check_published(entries, columns, file=None, lines=None, prefix=("published",), absent=None):
    """[Published] from a campaign's ``published`` list (schema-validated); ConfigError unless each
    statistic is one of the grammar's and each column one of the runs ``columns`` (``absent``:
    {column: why} of those the campaign does not produce, requirements.unproduced_columns)."""
    lines = lines or {}
    absent = absent or {}
    columns = [c for c in columns if c not in NOT_METRIC_COLUMNS] + [c for c in DERIVED_COLUMNS if c not in columns]

    def fail(message, *path):
        key = prefix + path
        line = next((lines[key[:k]] for k in range(len(key), 0, -1) if key[:k] in lines), None)
        raise ConfigError(message, file=file, line=line, path=key)

    parsed = []
    for i, entry in enumerate(entries):
        stat = entry["statistic"]
        if not valid_stat(stat):
            guess = difflib.get_close_matches(stat, SUGGESTED_STATS, n=1, cutoff=0.5)
            hint = f"did you mean '{guess[0]}'?" if guess else "expected one of the requirement statistics"
            fail(f"unknown statistic '{stat}'; {hint} ({', '.join(SUGGESTED_STATS)}, p<q>)", i, "statistic")
        for column in entry["values"]:
            if column in columns:
                continue
            if column in absent:
                fail(not_produced(f"published '{column}'", column, absent, columns).message, i, "values", column)
            guess = difflib.get_close_matches(column, columns, n=1, cutoff=0.6)
            if column in ORBIT_COLUMNS:
                hint = "it is a column of vehicles with the orbit trajectory only"
            elif column in POINTING_COLUMNS:
                hint = "it is a column of missions with a pointing window (pointing_statistics_from_s) only"
            elif column in WHEEL_COLUMNS:
                hint = "it is a column of vehicles with reaction wheels only"
            elif guess:
                hint = f"did you mean '{guess[0]}'?"
            else:
                hint = "expected a numeric column of this campaign's runs table (docs/interface.md)"
            fail(f"'{column}' is not a runs column of this campaign; {hint}", i, "values", column)
        parsed.append(Published(entry["source"], stat, dict(entry["values"])))
    return parsed
