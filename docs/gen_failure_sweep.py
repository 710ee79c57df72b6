"""Fly campaigns/failure-sweep.yaml in-process and print the result table of docs/failure-sweep.md.

Every single and double thruster failure (8 + 28 = 36 sets) plus the nominal run 0, undispersed;
each set is compared with 000 Table 4 (the compensable failures). Takes a few seconds after the
numba kernels are compiled (cached on disk).

    .venv/bin/python docs/gen_failure_sweep.py           # print the table
    .venv/bin/python docs/gen_failure_sweep.py --write   # replace it in docs/failure-sweep.md
"""

import math
import subprocess
import sys
from pathlib import Path

from refexmc.campaign.chunk import fly_chunk
from refexmc.config.load import load_campaign

ROOT = Path(__file__).resolve().parents[1]
CAMPAIGN = ROOT / "campaigns" / "failure-sweep.yaml"
DOC = Path(__file__).with_name("failure-sweep.md")
BEGIN = "<!-- sweep:begin -->"
END = "<!-- sweep:end -->"

# 000 Table 4: the compensable thruster failures (1-based thruster ids, ascending)
TABLE_4 = frozenset(
    [(1,), (2,), (3,), (4,), (7,), (8,)] + [(1, 2), (3, 4), (1, 3), (2, 4), (7, 8), (1, 8), (2, 8), (3, 7), (4, 7)]
)


def fly_sweep(campaign_file=CAMPAIGN):
    """(campaign, runs rows) of the failure sweep, flown in this process."""
    campaign = load_campaign(campaign_file)
    rows, _ = fly_chunk(campaign, range(campaign["runs"]))
    return campaign, rows


def failed_set(row):
    text = row["failed_thrusters"]
    return tuple(int(t) for t in text.split(",")) if text else ()


def number(value, fmt):
    return "—" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, fmt)


def completes(row):
    return row["status"] == "ok" and bool(row["success"])


def table(campaign, rows):
    """Markdown table: one line per run, with 000 Table 4's verdict and whether the two agree.

    The campaign's tank is large so that no run ends for want of propellant; the last columns say
    whether the propellant a run used fits the vehicle file's tank.
    """
    tank_kg = campaign["vehicle"]["rcs"]["propellant_kg"]
    lines = [
        "| run | failed thrusters | 000 Table 4 | completes | failure reason | modes completed "
        f"| t_end [s] | hand-over angle error [deg] | agrees | propellant used [kg] | fits the {tank_kg:g} kg tank |",
        "|---:|---|---|---|---|---:|---:|---:|---|---:|---|",
    ]
    for row in rows:
        failed = failed_set(row)
        done = completes(row)
        if failed:
            expected = failed in TABLE_4
            verdict = "compensable" if expected else "not compensable"
            agrees = "yes" if done == expected else "**no**"
        else:
            verdict, agrees = "— (nominal)", "—"
        used = row["fuel_used_kg"]
        cells = (
            str(row["run_id"]),
            f"[{', '.join(map(str, failed))}]" if failed else "none",
            verdict,
            "yes" if done else "no",
            row["failure_reason"] or "—",
            str(row["modes_completed"]),
            number(row["t_end_s"], ".1f"),
            number(row["attitude_error_end_deg"], ".3f"),
            agrees,
            number(used, ".3f"),
            ("yes" if used <= tank_kg else "**no**") if done else "—",
        )
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _names(group):
    return ", ".join(f"[{', '.join(map(str, s))}]" for s in group) or "none"


def summary(campaign, rows):
    """Agreement with 000 Table 4, the sets that complete, and those the tank does not cover."""
    tank_kg = campaign["vehicle"]["rcs"]["propellant_kg"]
    sets = [(failed_set(r), completes(r), r["fuel_used_kg"]) for r in rows if r["failed_thrusters"]]
    agree = sum(done == (failed in TABLE_4) for failed, done, _ in sets)
    complete = [failed for failed, done, _ in sets if done]
    short = [(failed, used) for failed, done, used in sets if done and used > tank_kg]
    nominal = [r for r in rows if not r["failed_thrusters"]]
    lines = [
        f"- Agreement with 000 Table 4: **{agree} of {len(sets)}** failure sets.",
        f"- Sets that complete ({len(complete)}): {_names(complete)}.",
        f"- Sets that fail ({len(sets) - len(complete)}): {_names([s for s, done, _ in sets if not done])}.",
        f"- Completing sets that need more than the vehicle's {tank_kg:g} kg tank ({len(short)}): "
        + (", ".join(f"[{', '.join(map(str, s))}] {used:.3f} kg" for s, used in short) or "none")
        + ".",
    ]
    if nominal:
        used = nominal[0]["fuel_used_kg"]
        state = "completes" if completes(nominal[0]) else "does NOT complete"
        lines.insert(0, f"- Nominal run (no failure): {state}, {used:.3f} kg used.")
    return "\n".join(lines) + "\n"


def provenance(script="docs/gen_failure_sweep.py"):
    """The commit the sweep was flown at, and whether the model sources had uncommitted changes."""
    source = Path(sys.modules["refexmc"].__file__).resolve().parents[1]

    def git(*args):
        try:
            return subprocess.run(
                ["git", "-C", str(source), *args], capture_output=True, text=True, check=True
            ).stdout.strip()
        except (OSError, subprocess.CalledProcessError):
            return None

    commit = git("rev-parse", "--short", "HEAD")
    if commit is None:
        return "Flown from a source tree that is not a git checkout (commit unknown)."
    dirty = git("status", "--porcelain", "--", "refexmc", "configs", "campaigns")
    state = " (the working tree had uncommitted changes under refexmc/, configs/ or campaigns/)" if dirty else ""
    return f"Flown with `.venv/bin/python {script}` at commit `{commit}`{state}."


def generate(campaign_file=CAMPAIGN):
    campaign, rows = fly_sweep(campaign_file)
    return f"{provenance()}\n\n{table(campaign, rows)}\n{summary(campaign, rows)}"


def write_between_markers(doc, generated):
    """Replace the text between BEGIN and END in ``doc`` with ``generated``."""
    head, rest = doc.read_text().split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    doc.write_text(f"{head}{BEGIN}\n{generated}{END}{tail}")


def main(argv, generate=generate, doc=DOC):
    """Print what ``generate()`` makes, or with ``--write`` put it between the markers of ``doc``."""
    generated = generate()
    if "--write" in argv:
        write_between_markers(doc, generated)
    else:
        sys.stdout.write(generated)


if __name__ == "__main__":
    main(sys.argv[1:])
