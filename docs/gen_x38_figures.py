"""Regenerates 003 Fig. 2 and Fig. 3 from configs/vehicles/x38.yaml: the propellant rate of the
blended allocation (003 eq. 8) over the free flap's elevon deflection, and over (elevon, rudder).

Usage::

    .venv/bin/python docs/gen_x38_figures.py      # writes docs/x38-fig2.png, docs/x38-fig3.png

The flight condition and the commanded moments are illustrative (003 gives none): alpha 33 deg
(where the vehicle trims with its flaps at 18 deg), Mach 20, q = 3 kPa for Fig. 2; alpha 30 deg,
Mach 5, q = 10 kPa for Fig. 3; the flap blocked at 20 deg in both, as in 003. The LP optimum
(core.blending) is marked on each.
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

from refexmc.config import entry  # noqa: E402
from refexmc.config.load import load_vehicle  # noqa: E402
from refexmc.core import aerodynamics as aero  # noqa: E402
from refexmc.core import blending  # noqa: E402

BLOCK_DEG = 20.0
TORQUE_N_M = np.array([300.0, -500.0, 150.0])  # l_c, m_c, n_c (illustrative)
CONDITIONS = {
    "fig2": {"alpha_deg": 33.0, "mach": 20.0, "qbar_pa": 3_000.0, "rudders": False},
    "fig3": {"alpha_deg": 30.0, "mach": 5.0, "qbar_pa": 10_000.0, "rudders": True},
}


def blend_problem(vehicle, alpha_deg, mach, qbar_pa, rudders):
    """(B, offset, lower, upper, weights) of the blending LP at one flight condition."""
    model = entry.model(vehicle, 6_371_000.0, 3.986004418e14, 7.2921159e-5)
    alpha = math.radians(alpha_deg)

    def c(slot):
        return aero.coefficient(model.alpha_axis, model.mach_axis, model.coefficients, slot, alpha, mach)

    trim = -c(aero.AC_PITCH) / c(aero.AC_PITCH_ELEVON)  # 003 eq. 6: delta_trim
    qsl = qbar_pa * model.reference[0] * model.reference[1]
    b, offset = np.zeros((3, 3)), np.zeros(3)
    blending.surface_moments(
        qsl, c(aero.AC_ROLL_AILERON), c(aero.AC_PITCH_ELEVON), c(aero.AC_YAW_AILERON),
        c(aero.AC_ROLL_RUDDER), c(aero.AC_YAW_RUDDER), trim, b, offset,
    )  # fmt: skip
    flaps, rudder = vehicle["surfaces"]["body_flaps"], vehicle["surfaces"]["rudders"]
    block = math.radians(BLOCK_DEG)  # the right flap
    rudder_low = math.radians(rudder["min_deg"]) if rudders else 0.0
    rudder_high = math.radians(rudder["max_deg"]) if rudders else 0.0
    lower = np.array([math.radians(flaps["min_deg"]), block, rudder_low])
    upper = np.array([math.radians(flaps["max_deg"]), block, rudder_high])
    return b, offset, lower, upper, entry.propellant_weights(vehicle)


def optimum(b, offset, lower, upper, weights):
    deflection, thrusters = np.zeros(3), np.zeros(3)
    work, basis = np.zeros(blending.scratch_shape()), np.zeros(3, dtype=np.int64)
    in_basis = np.zeros(blending.BLEND_COLUMNS, dtype=np.bool_)
    rate = blending.blend(b, offset, TORQUE_N_M, lower, upper, weights, deflection, thrusters, work, basis, in_basis)
    return rate, deflection


def rate_at(b, offset, weights, d):
    return float(weights @ np.abs(TORQUE_N_M - b @ d - offset))


def elevon(left, block):
    """003 eq. 7: delta_e = (left + right) / 2 with the right flap blocked."""
    return 0.5 * (left + block)


def fig2(vehicle, path):
    b, offset, lower, upper, weights = blend_problem(vehicle, **CONDITIONS["fig2"])
    block = lower[1]
    left = np.linspace(lower[0], upper[0], 400)
    rates = [rate_at(b, offset, weights, (x, block, 0.0)) * 1e3 for x in left]
    best, d = optimum(b, offset, lower, upper, weights)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    ax.plot(np.degrees(elevon(left, block)), rates, color="k")
    c = TORQUE_N_M - offset - b[:, 1] * block
    for i, label in enumerate(("9a: l = 0", "9b: m = 0", "9c: n = 0")):
        root = c[i] / b[i, 0]
        if lower[0] <= root <= upper[0]:
            ax.axvline(math.degrees(elevon(root, block)), ls="--", lw=0.8, color=f"C{i}", label=f"eq. {label}")
    ax.plot(math.degrees(elevon(d[0], block)), best * 1e3, "ro", label="LP optimum")
    ax.set_xlabel("elevon deflection delta_e [deg]")
    ax.set_ylabel("RCS propellant rate [g/s]")
    ax.set_title(f"Flap blocked at {BLOCK_DEG:.0f} deg, Mach 20 (cf. 003 Fig. 2)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def fig3(vehicle, path):
    b, offset, lower, upper, weights = blend_problem(vehicle, **CONDITIONS["fig3"])
    block = lower[1]
    left, dr = np.meshgrid(np.linspace(lower[0], upper[0], 200), np.linspace(lower[2], upper[2], 200))
    rates = np.vectorize(lambda x, y: rate_at(b, offset, weights, (x, block, y)))(left, dr) * 1e3
    best, d = optimum(b, offset, lower, upper, weights)
    fig, ax = plt.subplots(figsize=(6, 4.4))
    contour = ax.contourf(np.degrees(elevon(left, block)), np.degrees(dr), rates, levels=20, cmap="viridis")
    fig.colorbar(contour, label="RCS propellant rate [g/s]")
    c = TORQUE_N_M - offset - b[:, 1] * block
    line = np.linspace(lower[0], upper[0], 2)
    for i, label, style in ((0, "10a: l = 0", "--"), (2, "10c: n = 0", "-.")):
        rudder = (c[i] - b[i, 0] * line) / b[i, 2]
        ax.plot(np.degrees(elevon(line, block)), np.degrees(rudder), color="w", lw=0.9, ls=style, label=f"eq. {label}")
    ax.axvline(math.degrees(elevon(c[1] / b[1, 0], block)), color="w", lw=0.8, ls=":", label="eq. 10b: m = 0")
    ax.plot(math.degrees(elevon(d[0], block)), math.degrees(d[2]), "ro", label="LP optimum (lowest vertex)")
    ax.set_xlim(np.degrees(elevon(lower[0], block)), np.degrees(elevon(upper[0], block)))
    ax.set_ylim(np.degrees(lower[2]), np.degrees(upper[2]))
    ax.set_xlabel("elevon deflection delta_e [deg]")
    ax.set_ylabel("rudder deflection delta_r [deg]")
    ax.set_title(f"Flap blocked at {BLOCK_DEG:.0f} deg, Mach 5 (cf. 003 Fig. 3)")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main():
    vehicle = load_vehicle(ROOT / "configs/vehicles/x38.yaml")
    fig2(vehicle, ROOT / "docs/x38-fig2.png")
    fig3(vehicle, ROOT / "docs/x38-fig3.png")
    for name, condition in CONDITIONS.items():
        problem = blend_problem(vehicle, **condition)
        rate, d = optimum(*problem)
        delta_e, delta_r = math.degrees(elevon(d[0], d[1])), math.degrees(d[2])
        print(f"{name}: optimum delta_e {delta_e:.2f} deg, delta_r {delta_r:.2f} deg, {rate * 1e3:.2f} g/s")


if __name__ == "__main__":
    main()
