"""Print the table of dispersible parameter paths for docs/campaigns.md.

The table is generated from ``refexmc.config.parameters.PARAMETERS`` (the one declaration of
each path that validation, dispersion, packing and these docs read), so the documentation
cannot drift from the code unnoticed:
``tests/test_docs.py`` compares the table in docs/campaigns.md with this script's output.

    .venv/bin/python docs/gen_parameter_table.py           # print the table
    .venv/bin/python docs/gen_parameter_table.py --write   # replace it in docs/campaigns.md
"""

import math
import sys
from pathlib import Path

from refexmc.config.parameters import AXES, DEG, INERTIA_COMPONENTS, MISSION_ROOTS, PARAMETERS, schema_default

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


def nominal_source(param):
    """Where the nominal value of ``param`` comes from (dispersions.nominal)."""
    entry = param.path.startswith("entry_flight.")
    if param.key is None:
        return f"{param.nominal:g} (dispersion only{'; entry mission' if entry else ''})"
    if entry:
        return "entry mission file"
    if param.path.startswith("rcs.valve_time_constants_ms."):
        return "vehicle file, one value for every thruster"
    text = "mission file" if param.path.split(".")[0] in MISSION_ROOTS else "vehicle file"
    if "[]" in param.key:
        text += f", `{param.key.split('[]')[0]}[*]`"
    default = schema_default(param.key)
    if isinstance(default, list):  # a vector's default: every component the same
        default = default[0]
    return text if default is None else f"{text} (default {default:g})"


def lands_in(param):
    """Where the value goes in the packed run inputs: a field (and what else it sets), or the special case's reason."""
    if param.table is None:
        return param.special
    scale = "" if param.scale == 1.0 else " (deg to rad)" if param.scale == DEG else f" (times {param.scale:g})"
    return f"`{param.table}.{param.field}`{scale}" + (f"; {param.special}" if param.special else "")


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
        "| path | unit | components, `p.<path>` columns | physical range | nominal from | distributions | meaning "
        "| lands in |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for path, param in PARAMETERS.items():
        cells = (
            f"`{path}`",
            param.unit,
            _COMPONENTS[param.shape],
            range_text(param),
            nominal_source(param),
            _DISTRIBUTIONS.get(param.shape, _DEFAULT_DISTRIBUTIONS),
            param.doc,
            lands_in(param),
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
