"""Print the table of dispersible parameter paths for docs/campaigns.md.

The table is generated from ``refexmc.config.dispersions.PARAMETERS`` (the registry the campaign
loader checks against), so the documentation cannot drift from the code unnoticed:
``tests/test_docs.py`` compares the table in docs/campaigns.md with this script's output.

    .venv/bin/python docs/gen_parameter_table.py           # print the table
    .venv/bin/python docs/gen_parameter_table.py --write   # replace it in docs/campaigns.md
"""

import math
import sys
from pathlib import Path

from refexmc.config.dispersions import AXES, INERTIA_COMPONENTS, PARAMETERS

DOC = Path(__file__).with_name("campaigns.md")
BEGIN = "<!-- parameters:begin -->"
END = "<!-- parameters:end -->"

# components and p.<path> column suffixes per Parameter.shape (dispersions.components)
_COMPONENTS = {
    "scalar": "scalar: `p.<path>`",
    "vector": "3, body axes: `.{}`".format("` `.".join(AXES)),
    "attitude": "3, rotation vector: `.{}`".format("` `.".join(AXES)),
    "thruster": "1 per thruster: `.1` ... `.N`",
    "wheel": "1 per reaction wheel: `.1` ... `.N`",
    "derating": "1 per `rcs.derating` entry: `.1` ... `.K`",
    "inertia": "6 tensor entries: `.{}`".format("` `.".join(INERTIA_COMPONENTS)),
}
# distributions a path of each shape takes (dispersions.check: inertia only on the inertia
# tensor, uniform_so3 only on the attitude, the others on every other path)
_DISTRIBUTIONS = {
    "inertia": "`inertia` only",
    "attitude": "all but `inertia`",
}
_DEFAULT_DISTRIBUTIONS = "all but `inertia`, `uniform_so3`"
# shapes whose range is not a per-component interval
_RANGE = {
    "inertia": "physical tensor (draws redrawn until physical)",
    "attitude": "any rotation",
}


def nominal_source(path):
    """Where the nominal value of ``path`` comes from (dispersions.nominal)."""
    if path in ("rcs.thrust_scale", "atmosphere.density_scale", "entry_flight.density_scale"):
        return "1 (dispersion only)"
    if path.startswith("entry_flight.coefficient_scale."):
        return "1 (dispersion only; entry mission)"
    if path.startswith("entry_flight."):
        return "entry mission file"
    if path.startswith("rcs.valve_time_constants_ms."):
        return "vehicle file, one value for every thruster"
    if path.split(".")[0] in ("separation", "navigation"):
        return "mission file"
    if path == "wheels.initial_momentum_n_m_s":
        return "vehicle file, `wheels.units[*]` (default 0)"
    return "vehicle file"


def range_text(param):
    """Physical range of every component, as the support check applies it."""
    if param.shape in _RANGE:
        return _RANGE[param.shape]
    if param.lower == -math.inf and param.upper == math.inf:
        return "any finite"
    if param.upper == math.inf:
        return f"{'>=' if param.lower_inclusive else '>'} {param.lower:g}"
    if param.lower == -math.inf:
        return f"<= {param.upper:g}"
    bracket = "[" if param.lower_inclusive else "("
    return f"{bracket}{param.lower:g}, {param.upper:g}]"


def _cell(text):
    return str(text).replace("|", "\\|")


def table():
    """The markdown table, one row per dispersible path, in registry order."""
    lines = [
        "| path | unit | components, `p.<path>` columns | physical range | nominal from | distributions | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    for path, param in PARAMETERS.items():
        cells = (
            f"`{path}`",
            param.unit,
            _COMPONENTS[param.shape],
            range_text(param),
            nominal_source(path),
            _DISTRIBUTIONS.get(param.shape, _DEFAULT_DISTRIBUTIONS),
            param.doc,
        )
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(lines) + "\n"


def replace_between_markers(text, generated, begin=BEGIN, end=END):
    """``text`` with everything between the marker lines replaced by ``generated``."""
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    return f"{head}{begin}\n{generated}{end}{tail}"


def main(argv):
    generated = table()
    if "--write" in argv:
        DOC.write_text(replace_between_markers(DOC.read_text(), generated))
    else:
        sys.stdout.write(generated)


if __name__ == "__main__":
    main(sys.argv[1:])
