"""Discrete causes as factors of "what drives" (``summary.sensitivity``): each failed unit (a
thruster or valve, a reaction wheel), the failure set (which units failed, "" for none: one
factor of all the sets, when more than one set occurs), and each input drawn from a ``choice``
distribution.

They are ranked with the continuous inputs on one scale, the share of the output's rank variance
the factor explains, eta^2 of the ranks (``stats.rank_eta2``): for a continuous input its
Spearman rho^2 (the monotone part), for a factor the correlation ratio of the output's ranks over
its levels. For a unit's failure indicator (two levels) the two coincide: eta^2 is the rho^2 of
the indicator, and the entry keeps that rho's sign (+: the runs with the failure rank higher).
A factor's significance is the Kruskal-Wallis test, H = (n - 1) eta^2 on chi^2 with levels - 1
degrees of freedom (the Mann-Whitney test for two levels). A factor with fewer than two runs per
level on average (a failure sweep's set, one run each) is not ranked: its eta^2 is near 1 by chance
alone, so its row has ``supported: false``, a ``flag`` and the ``runs_needed``, no eta^2 or p.

A factor is named for what it is: ``wheel 1 failed (undetected)``, ``thruster 3 failed
(detected)`` (the campaign's ``detected``: whether the flight software knew), ``failed wheel set
(undetected)``, ``rcs.isp_s (choice of 3 values)``; never a ``p.`` name.
"""

import numpy as np
import pandas as pd

from refexmc.report import stats

# (runs column, unit word, campaign key whose ``detected`` says whether the flight software knew)
UNIT_COLUMNS = (("failed_thrusters", "thruster", "failures"), ("failed_wheels", "wheel", "wheel_failures"))
INPUT_PREFIX = "p."


def _units(text):
    return [int(u) for u in str(text or "").split(",") if u.strip()]


def choice_columns(campaign):
    """``p.`` columns of inputs drawn from a ``choice`` distribution (categorical, not ordered by rank)."""
    dispersions = campaign.resolved.get("dispersions") or {}
    paths = [path for path, spec in dispersions.items() if spec.get("dist") == "choice"]
    return [
        c
        for c in campaign.parameter_columns
        if any(c == f"{INPUT_PREFIX}{path}" or c.startswith(f"{INPUT_PREFIX}{path}.") for path in paths)
    ]


def factors(campaign, runs):
    """[(name, kind, labels)] of the discrete factors that vary over ``runs`` (a runs table, e.g. the
    ok runs): ``labels`` one value per run; kinds "failure" (a unit's indicator, labels 0/1),
    "failure set" and "categorical"."""
    found = []
    for column, word, key in UNIT_COLUMNS:
        if column not in runs:
            continue
        known = "detected" if (campaign.resolved.get(key) or {}).get("detected", False) else "undetected"
        # each distinct text parsed once, then spread to the runs by its code (10^6 runs: few texts)
        codes, texts = pd.factorize(runs[column].to_numpy(), use_na_sentinel=False)
        sets = [_units(None if pd.isna(text) else text) for text in texts]
        units = sorted({u for s in sets for u in s})
        for unit in units:
            labels = np.array([unit in s for s in sets], dtype=np.int8)[codes]
            if 0 < labels.sum() < len(labels):
                found.append((f"{word} {unit} failed ({known})", "failure", labels))
        joined = [",".join(map(str, sorted(s))) for s in sets]
        labels = np.array(joined or [""], dtype=object)[codes]
        if len(set(joined) - {""}) > 1:  # which unit(s) failed, jointly: a cause no single indicator holds
            found.append((f"failed {word} set ({known})", "failure set", labels))
    for column in choice_columns(campaign):
        labels = runs[column].to_numpy(dtype=float)
        levels = len(np.unique(labels[np.isfinite(labels)]))
        if levels > 1:
            found.append((f"{column[len(INPUT_PREFIX) :]} (choice of {levels} values)", "categorical", labels))
    return found


MIN_RUNS_PER_LEVEL = 2  # on average: as many runs beyond one per level as there are levels


def replication_flag(n, levels):
    """Why a factor's eta^2 is not supported ('' when it is): with n runs over k levels, eta^2 of
    chance alone is (k - 1) / (n - 1) (1 with one run per level: a failure sweep's sets); the
    factor needs ``MIN_RUNS_PER_LEVEL`` runs per level on average to be ranked."""
    if n >= MIN_RUNS_PER_LEVEL * levels:
        return ""
    chance = (levels - 1) / (n - 1) if n > 1 else 1.0
    within = "no within-level replication" if n == levels else f"{n - levels} runs beyond one per level"
    return (
        f"not supported: {n} runs over {levels} levels ({within}); eta2 of chance alone is {chance:.2f}, "
        f"{MIN_RUNS_PER_LEVEL * levels} runs would rank it"
    )


def factor_rows(found, output, keep):
    """Sensitivity entries of the factors ``found`` against ``output`` over the runs ``keep``."""
    output_ranks = stats.average_ranks(output[keep])
    rows = []
    for name, kind, labels in found:
        labels = labels[keep]
        eta2, p, levels = stats.rank_eta2(output_ranks, labels)
        if levels < 2 or not np.isfinite(eta2):
            continue
        row = {"parameter": name, "kind": kind, "levels": levels, "eta2": eta2, "p_value": p, "rho": None}
        row.update(prcc=None, prcc_p_value=None)
        flag = replication_flag(len(labels), levels)
        if flag:  # eta^2 of chance alone is (k - 1) / (n - 1): 1 with one run per level
            row.update(eta2=None, p_value=None, supported=False, flag=flag, runs_needed=MIN_RUNS_PER_LEVEL * levels)
            rows.append(row)
            continue
        if kind == "failure":  # two levels: eta^2 = rho^2 of the indicator; rho's sign says which way
            failed = labels.astype(bool)
            row["runs_with"] = int(failed.sum())
            sign = 1.0 if output_ranks[failed].mean() >= output_ranks[~failed].mean() else -1.0
            row["rho"] = float(sign * np.sqrt(eta2))
        else:  # which levels push the output up: by their mean rank, highest first ("" = no failure)
            row["levels_by_rank"] = level_ranks(output_ranks, labels)
        rows.append(row)
    return rows


def level_ranks(output_ranks, labels, most=8):
    """[{level, runs, mean_rank}] of a factor's levels, highest mean output rank first (at most ``most``);
    mean ranks as a fraction of the runs (0.5: the middle)."""
    text = np.asarray(labels).astype(str)
    levels = []
    for level in np.unique(text):
        here = output_ranks[text == level]
        levels.append({"level": level, "runs": int(len(here)), "mean_rank": float(here.mean() / len(output_ranks))})
    levels.sort(key=lambda entry: -entry["mean_rank"])
    return levels[:most]
