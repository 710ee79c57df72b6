"""How a mission's flight ends, in the mission's own words (issue 26, part 3).

A flight ends when its last mode exits. ReFEx's last mode hands over to the aerodynamic control
at a dynamic pressure (000 sec. 2.2): only a mission whose last mode exits on
``dynamic_pressure_above_pa`` is said to end in a "hand-over"; any other mission's flight just
"ends". The runs-table columns are the same for every mission (``t_end_s``; ``attitude_error_end_deg``:
the total attitude error when the last mode ends, issue 34).
"""


def _number(value):
    return f"{value:g}" if isinstance(value, float) else str(value)


def exit_condition_text(exit_list):
    """``[{a: 1, b: true}, {c: 2}]`` -> ``"a 1 and b, or c 2"`` (each dict all of, the list any of)."""
    alternatives = []
    for condition in exit_list:
        parts = [key if value is True else f"{key} {_number(value)}" for key, value in condition.items()]
        alternatives.append(" and ".join(parts))
    return ", or ".join(alternatives)


def has_handover(mission):
    """Whether the mission ends by handing over to aerodynamic control (its last mode exits on q-bar)."""
    last = mission["modes"][-1]
    return any("dynamic_pressure_above_pa" in condition for condition in last.get("exit", []))


def end_name(mission):
    """``"hand-over"`` or ``"end"``: what the instant the flight stops is called."""
    return "hand-over" if has_handover(mission) else "end"


def end_condition(mission):
    """One line: the mode whose exit ends the flight and its exit conditions, and the flight-time cap."""
    last = mission["modes"][-1]
    text = f"{end_name(mission)} when {last['name']} exits on {exit_condition_text(last.get('exit', []))}"
    if last.get("timeout_s") is not None:
        text += f" (its timeout {_number(last['timeout_s'])} s fails the flight)"
    return text
