"""Draw 002 Fig. 8 again (docs/cold-gas-fig8.png): the time-optimal law and bang-bang from
x0 = [0.6, 0.5, 2.5] on the normalised plant eq. 21 (core.time_optimal.fly_normalised, the
closed form between 1 kHz samples), states and command over time.

Usage: .venv/bin/python docs/gen_cold_gas_fig8.py   (writes docs/cold-gas-fig8.png)
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from refexmc.core import time_optimal as to  # noqa: E402

X0 = (0.6, 0.5, 2.5)  # 002 sec. 5
X3_MIN = 0.5
DT = 1e-3
OUT = Path(__file__).resolve().parent / "cold-gas-fig8.png"


def fly(bang_bang):
    history = np.zeros((20_000, to.TO_HISTORY_SIZE))
    steps, arrived = to.fly_normalised(*X0, X3_MIN, DT, bang_bang, 1e-3, history.shape[0], history)
    assert arrived
    return history[: steps + 1]


def main():
    law, bang = fly(False), fly(True)
    fig, axes = plt.subplots(4, 1, sharex=True, figsize=(7.0, 8.0))
    labels = ("position x1", "velocity x2", "fuel x3", "command u")
    columns = (to.TO_X1, to.TO_X2, to.TO_X3, to.TO_U)
    for ax, label, column in zip(axes, labels, columns, strict=True):
        ax.plot(law[:, to.TO_T], law[:, column], label="time optimal (eq. 44)")
        ax.plot(bang[:, to.TO_T], bang[:, column], "--", label="bang-bang (sigma2)")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[2].axhline(X3_MIN, color="grey", lw=0.8, label="x3_min")
    axes[0].legend(loc="upper right")
    axes[-1].set_xlabel("time (normalised: t / tau)")
    fig.suptitle("002 Fig. 8: x0 = [0.6, 0.5, 2.5], arrival |x1|, |x2| <= 1e-3")
    fig.tight_layout()
    fig.savefig(OUT, dpi=90)
    print(f"law: t_end {law[-1, to.TO_T]:.4f}, x3 end {law[-1, to.TO_X3]:.4f}")
    print(f"bang-bang: t_end {bang[-1, to.TO_T]:.4f}, x3 end {bang[-1, to.TO_X3]:.4f}")


if __name__ == "__main__":
    main()
