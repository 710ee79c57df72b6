"""Prints the ``entry_aerodynamics.coefficients`` block of ``x38.yaml``: ESTIMATES for the X-38
over (alpha, Mach), from modified-Newtonian flow where the flow is hypersonic and linear
supersonic theory below; 003 publishes no coefficients. docs/x38.md gives each reason.

Usage::

    .venv/bin/python configs/vehicles/gen_x38_aero.py    # paste its output into x38.yaml

tests/test_x38_config.py checks that x38.yaml holds what this prints.
"""

import math

ALPHA_DEG = [0.0, 10.0, 20.0, 30.0, 35.0, 40.0, 45.0, 50.0]
MACH = [1.2, 2.0, 3.0, 4.0, 6.0, 10.0, 15.0, 20.0, 30.0]
AREA_M2 = 22.7  # 003 Table 1
LENGTH_M = 8.7  # X-38 V-201 length (NASA), the reference length of every moment
NEWTONIAN_FACTOR = 0.75  # C_N = 2 k sin^2(alpha): a blunt lifting body keeps ~75 % of a flat plate's
AXIAL_HYPERSONIC = 0.08  # C_A at Mach >> 1; with k gives L/D = 0.92 at 40 deg, Mach 20 (003: "about 0.9")
AXIAL_WAVE = 0.12  # C_A grows as 0.12 / Mach towards low supersonic speeds (base and wave drag)
FLAP_AREA_RATIO = 2.2 / AREA_M2  # two body flaps of ~1.1 m^2 each (estimate from the X-38 planform)
FLAP_ARM_X_M = 4.0  # flap hinge line to the centre of mass
FLAP_ARM_Y_M = 1.0  # each flap's centre from the plane of symmetry
RUDDER_AREA_RATIO = 1.2 / AREA_M2  # two fin-tip rudders of ~0.6 m^2
RUDDER_ARM_X_M = 4.2
RUDDER_ARM_Z_M = 1.2  # above the centre of mass
SIDESLIP = {"side": -0.5, "roll": -0.1}  # C_Y_beta, C_l_beta per rad: a stable lifting body (estimate)


def trim_deflection_deg(alpha_deg):
    """Flap deflection that trims the pitch moment: 20 deg at alpha 30, 0.6 deg less per deg of
    alpha, so that a 14 deg flap trims at alpha 40 and a lower flap needs a higher alpha, as in
    003 ("the commanded angle of attack has to be increased")."""
    return 20.0 - 0.6 * (alpha_deg - 30.0)


def tables():
    out = {}
    for key in (
        "lift",
        "drag",
        "side_force_per_beta_rad",
        "roll_per_beta_rad",
        "pitch",
        "yaw_per_beta_rad",
        "roll_per_aileron_rad",
        "pitch_per_elevon_rad",
        "yaw_per_aileron_rad",
        "roll_per_rudder_rad",
        "yaw_per_rudder_rad",
    ):
        out[key] = []
    for alpha_deg in ALPHA_DEG:
        a = math.radians(alpha_deg)
        rows = {key: [] for key in out}
        for mach in MACH:
            linear = min(1.4 / math.sqrt(mach * mach - 1.0), 2.0)  # supersonic lift slope, fades at high Mach
            normal = 2.0 * NEWTONIAN_FACTOR * math.sin(a) ** 2 + linear * math.sin(a) * math.cos(a)
            axial = AXIAL_HYPERSONIC + AXIAL_WAVE / mach
            flap_incidence = a + math.radians(trim_deflection_deg(alpha_deg))
            flap_normal = FLAP_AREA_RATIO * 2.0 * math.sin(2.0 * flap_incidence)  # d(2 sin^2 theta)/d theta
            pitch_elevon = -flap_normal * FLAP_ARM_X_M / LENGTH_M
            roll_aileron = flap_normal * FLAP_ARM_Y_M / LENGTH_M
            rudder_side = RUDDER_AREA_RATIO * min(4.0 / math.sqrt(mach * mach - 1.0), 2.5)
            rows["lift"].append(normal * math.cos(a) - axial * math.sin(a))
            rows["drag"].append(normal * math.sin(a) + axial * math.cos(a))
            rows["side_force_per_beta_rad"].append(SIDESLIP["side"])
            rows["roll_per_beta_rad"].append(SIDESLIP["roll"])
            rows["pitch"].append(-pitch_elevon * math.radians(trim_deflection_deg(alpha_deg)))
            rows["yaw_per_beta_rad"].append(0.06 - 0.12 * math.sin(a) ** 2)  # directionally unstable at high alpha
            rows["roll_per_aileron_rad"].append(roll_aileron)
            rows["pitch_per_elevon_rad"].append(pitch_elevon)
            rows["yaw_per_aileron_rad"].append(-0.3 * roll_aileron)  # adverse yaw of the flaps' drag
            rows["roll_per_rudder_rad"].append(rudder_side * RUDDER_ARM_Z_M / LENGTH_M)
            rows["yaw_per_rudder_rad"].append(-rudder_side * RUDDER_ARM_X_M / LENGTH_M)
        for key in out:
            out[key].append([round(v, 5) for v in rows[key]])
    return out


def main():
    print("  coefficients:")
    for key, table in tables().items():
        print(f"    {key}:")
        for row in table:
            print("      - [" + ", ".join(f"{v:.5f}" for v in row) + "]")


if __name__ == "__main__":
    main()
