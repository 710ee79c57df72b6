"""Fly one run: allocate the caller-owned output arrays and call the core."""

import math
from typing import NamedTuple

import numpy as np

from refexmc.core import layout as L
from refexmc.core.flight import run_flight


class FlightResult(NamedTuple):
    summary: np.ndarray  # layout.SUMMARY
    pulse_counts: np.ndarray  # valve open commands sent, per thruster
    history: np.ndarray  # rows x layout.HISTORY_SIZE

    def value(self, name):
        offset, size = L.SUMMARY.slices[name]
        return self.summary[offset] if size == 1 else self.summary[offset : offset + size]

    @property
    def success(self):
        return bool(self.summary[L.S_SUCCESS])

    @property
    def failure_reason(self):
        return L.FAILURE_NAMES[int(self.summary[L.S_FAILURE])]

    def column(self, name):
        offset, size = L.HISTORY.slices[name]
        return self.history[:, offset] if size == 1 else self.history[:, offset : offset + size]


def history_every(inputs, history_rate_hz):
    """Control steps between history samples (at least 1)."""
    period = inputs.fsw[L.F_CONTROL_PERIOD]
    return max(1, int(round(1.0 / (history_rate_hz * period))))


def fly(inputs, nav_seed=0, history_rate_hz=2.0):
    """Run one flight with ``inputs`` (config.pack.RunInputs); history at ``history_rate_hz``."""
    every = history_every(inputs, history_rate_hz)
    period = inputs.fsw[L.F_CONTROL_PERIOD]
    max_rows = int(math.ceil(inputs.mission[L.M_MAX_TIME] / period / every)) + 3
    summary = np.zeros(L.SUMMARY_SIZE)
    pulses = np.zeros(inputs.thrusters.shape[0], dtype=np.int64)
    history = np.zeros((max_rows, L.HISTORY_SIZE))
    run_flight(
        inputs.vehicle,
        inputs.thrusters,
        inputs.fsw,
        inputs.mission,
        inputs.nav,
        inputs.atmosphere,
        inputs.allocation,
        np.int64(nav_seed),
        np.int64(every),
        summary,
        pulses,
        history,
    )
    rows = int(summary[L.S_HISTORY_ROWS])
    return FlightResult(summary, pulses, history[:rows])
