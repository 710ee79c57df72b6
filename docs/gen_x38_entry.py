"""Flies the X-38 entry of tests/test_entry_flight.py (core.entry_flight) nominal and with the
right flap blocked at 10-20 deg, and prints a markdown table of RCS propellant and loads beside
003's figures; writes docs/x38-entry.png (time histories, cf. 003 Fig. 6) for the 14 deg case.

Usage::

    .venv/bin/python docs/gen_x38_entry.py

A deterministic sweep, not a Monte-Carlo campaign: one entry state, the schedules of the test,
no dispersions (docs/x38.md says what is still missing).
"""

import math
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

import test_entry_flight as flight  # noqa: E402

from refexmc.core import entry_flight as ef  # noqa: E402

BLOCKS_DEG = (None, 10.0, 12.0, 14.0, 16.0, 18.0, 20.0)
# the truth apart from the flight software's model (config.entry.entry_vehicle keywords)
TRUTH_CASES = (
    ("density +20 %", None, {"density_factor": 1.2}),
    ("density -20 %", None, {"density_factor": 0.8}),
    (
        "C_L -10 %, C_m +10 %, C_m_delta_e and C_l_delta_a -20 %",
        None,
        {"coefficient_factors": {"lift": 0.9, "pitch": 1.1, "pitch_per_elevon_rad": 0.8, "roll_per_aileron_rad": 0.8}},
    ),
    ("right flap blocked at 14°, C_m +10 %, C_m_delta_e -20 %", ("right", 14.0),
     {"coefficient_factors": {"pitch": 1.1, "pitch_per_elevon_rad": 0.8}}),
    ("right flap blocked at 14°, unknown to the flight software", ("right", 14.0), {"blocked_known": False}),
    ("left flap blocked at 14°, unknown to the flight software", ("left", 14.0), {"blocked_known": False}),
)  # fmt: skip


def main():
    print(
        "| flap | RCS propellant [kg] | flight time [s] | peak q [kPa] | peak load [g] | peak heat flux [kW/m²] "
        "| down-range [km] | cross-range [km] | max alpha error [deg] | max bank error [deg] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    histories = {}
    for block in BLOCKS_DEG:
        summary, history = flight.fly(None if block is None else ("right", block))
        histories[block] = history
        label = "nominal (both free)" if block is None else f"right blocked at {block:.0f}°"
        print(
            f"| {label} | {summary[ef.SU_PROPELLANT]:.1f} | {summary[ef.SU_TIME]:.0f} | "
            f"{summary[ef.SU_PEAK_QBAR] / 1e3:.1f} | {summary[ef.SU_PEAK_LOAD]:.2f} | "
            f"{summary[ef.SU_PEAK_HEAT_FLUX] / 1e3:.0f} | {summary[ef.SU_DOWN_RANGE] / 1e3:.0f} | "
            f"{summary[ef.SU_CROSS_RANGE] / 1e3:.0f} | "
            f"{math.degrees(summary[ef.SU_ALPHA_ERROR]):.2f} | {math.degrees(summary[ef.SU_BANK_ERROR]):.2f} |"
        )
    print()
    print("| truth against the flight software's model | RCS propellant [kg] | max alpha error [deg] "
          "| max bank error [deg] | max sideslip [deg] |")  # fmt: skip
    print("|---|---|---|---|---|")
    for label, blocked, truth in TRUTH_CASES:
        summary, _ = flight.fly(blocked, **truth)
        print(
            f"| {label} | {summary[ef.SU_PROPELLANT]:.1f} | {math.degrees(summary[ef.SU_ALPHA_ERROR]):.2f} | "
            f"{math.degrees(summary[ef.SU_BANK_ERROR]):.2f} | {math.degrees(summary[ef.SU_BETA_ERROR]):.2f} |"
        )
    history = histories[14.0]
    t = history[:, ef.HI_TIME]
    fig, axes = plt.subplots(4, 1, figsize=(6.5, 8), sharex=True)
    axes[0].plot(t, history[:, ef.HI_ALTITUDE] / 1e3, "k")
    axes[0].set_ylabel("altitude [km]")
    axes[1].plot(t, np.degrees(history[:, ef.HI_ALPHA]), "k", label="alpha")
    axes[1].plot(t, np.degrees(history[:, ef.HI_BANK]), "C0", label="bank")
    axes[1].set_ylabel("[deg]")
    axes[1].legend(fontsize=8)
    axes[2].plot(t, np.degrees(history[:, ef.HI_LEFT]), "k", label="free flap")
    axes[2].plot(t, np.degrees(history[:, ef.HI_RIGHT]), "C3", label="blocked flap")
    axes[2].plot(t, np.degrees(history[:, ef.HI_RUDDER]), "C0", label="rudders")
    axes[2].set_ylabel("deflection [deg]")
    axes[2].legend(fontsize=8)
    axes[3].plot(t, history[:, ef.HI_PROPELLANT], "k")
    axes[3].set_ylabel("RCS propellant [kg]")
    axes[3].set_xlabel("time from 121.9 km [s]")
    fig.suptitle("X-38, right flap blocked at 14 deg (cf. 003 Fig. 6)")
    fig.tight_layout()
    fig.savefig(ROOT / "docs/x38-entry.png", dpi=80)
    plt.close(fig)


if __name__ == "__main__":
    main()
