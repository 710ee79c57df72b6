"""Names for any mission (issue 34): the keys, parameter paths, runs columns and failure reasons
that carried ReFEx's words, and the one place that maps their old names to the new ones.

- mission files: ``separation`` is ``initial_state`` (the state at t = 0 of any mission), its
  ``attitude_error_deg`` is ``attitude_rotvec_deg`` (the initial attitude itself, a rotation vector
  from the reference axes: body x along the velocity with a trajectory, else the inertial axes;
  not an error from any mode's target), ``handover_max_angle_deg`` is
  ``attitude_error_end_max_deg``;
- parameter paths ``separation.*`` are ``initial_state.*`` (and their ``p.`` columns);
- the runs column ``theta_t_handover_deg`` is ``attitude_error_end_deg`` (the total attitude error
  when the last mode ends, in degrees), the failure reason ``handover_angle_error`` is
  ``attitude_error_end_above_max``.

A file with an old name still loads: each old name is a warning naming the new one (file, line,
key path), an error under ``--strict`` (:func:`migrate_campaign`, :func:`migrate_mission`).
An output written before the rename is read as if written after it: its runs parts
(:func:`runs_table`), its resolved campaign (the same migration, silent) and its manifest's
column list. A renamed path keeps drawing the values it drew under its first name
(:func:`seed_path`): a campaign's runs are the same bits apart from the renamed columns.
"""

import functools
import re

OLD_BLOCK, NEW_BLOCK = "separation", "initial_state"
BLOCK_KEYS = {"attitude_error_deg": "attitude_rotvec_deg"}  # keys renamed inside the block
MISSION_KEYS = {"handover_max_angle_deg": "attitude_error_end_max_deg"}  # top-level keys of a mission
PATHS = {
    f"{OLD_BLOCK}.{key}": f"{NEW_BLOCK}.{BLOCK_KEYS.get(key, key)}"
    for key in ("altitude_m", "speed_m_s", "flight_path_angle_deg", "rates_deg_s", "attitude_error_deg")
}
COLUMNS = {"theta_t_handover_deg": "attitude_error_end_deg"}
FAILURE_REASONS = {"handover_angle_error": "attitude_error_end_above_max"}
_SEED_PATHS = {new: old for old, new in PATHS.items()}

# an old column or path inside a metric or requirement text ('theta_t_handover_deg.max <= 5')
_OLD_NAMES = sorted([*COLUMNS, *PATHS], key=len, reverse=True)
_OLD_NAME = re.compile(r"(?<![\w.])(p\.)?(" + "|".join(re.escape(name) for name in _OLD_NAMES) + r")(?!\w)")


def seed_path(path):
    """The name that keys ``path``'s draws (campaign.sampling.path_key): the path as first named."""
    return _SEED_PATHS.get(path, path)


def new_path(path):
    return PATHS.get(path, path)


def new_column(name):
    """The current name of runs column ``name`` (``p.<old path>[.<component>]`` included)."""
    if name in COLUMNS:
        return COLUMNS[name]
    if name.startswith(f"p.{OLD_BLOCK}."):
        for old, new in PATHS.items():
            if name == f"p.{old}" or name.startswith(f"p.{old}."):
                return f"p.{new}" + name[len(old) + 2 :]
    return name


def new_text(text):
    """``text`` (a metric, a requirement, an event) with every old column or path renamed."""
    return _OLD_NAME.sub(lambda m: (m.group(1) or "") + (COLUMNS.get(m.group(2)) or PATHS[m.group(2)]), text)


def runs_table(table, reasons=True):
    """A runs part (pyarrow Table) with the current column names and (``reasons``) failure reasons.
    ``reasons=False`` leaves the reasons to one :func:`runs_failure_reasons` of the joined parts."""
    names = _new_columns(tuple(table.column_names))
    if names is not None:
        table = table.rename_columns(names)
    return runs_failure_reasons(table) if reasons else table


@functools.lru_cache(maxsize=16)
def _new_columns(names):
    """The current names of runs columns ``names`` (a tuple), None when they are current: the
    parts of one output share their names, so a campaign of 10,000 parts maps them once."""
    renamed = [new_column(name) for name in names]
    return None if renamed == list(names) else renamed


def runs_failure_reasons(table):
    """A runs table (pyarrow) with the current failure reasons."""
    import pyarrow as pa
    import pyarrow.compute as pc

    names = table.column_names
    if "failure_reason" in names:
        column = table.column("failure_reason")
        if pa.types.is_string(column.type) and pc.any(pc.is_in(column, pa.array(list(FAILURE_REASONS)))).as_py():
            renamed = pa.array([FAILURE_REASONS.get(v, v) for v in column.to_pylist()], type=column.type)
            table = table.set_column(names.index("failure_reason"), "failure_reason", renamed)
    return table


def _rename_key(node, old, new, lines, path):
    """Rename key ``old`` of dict ``node`` (at key path ``path``) to ``new`` in place, order kept,
    with the line map's entries under it; returns whether it was there. Both given: the old stays
    (the schema then refuses it as unknown)."""
    if not isinstance(node, dict) or old not in node or new in node:
        return False
    items = list(node.items())
    node.clear()
    node.update((new if key == old else key, value) for key, value in items)
    if lines is not None:
        old_path, size = (*path, old), len(path) + 1
        for key in [k for k in lines if k[:size] == old_path]:
            lines[(*path, new, *key[size:])] = lines[key]
    return True


def migrate_mission(mission, lines=None, prefix=()):
    """Rename the old keys of a mission (read from YAML, at key path ``prefix``) in place, the line
    map ``lines`` (key path -> line, relative to ``prefix``) with them. Returns [(old key path,
    message)], one per old name found."""
    found = []
    if not isinstance(mission, dict):
        return found
    if _rename_key(mission, OLD_BLOCK, NEW_BLOCK, lines, ()):
        found.append(((OLD_BLOCK,), f"'{OLD_BLOCK}' is now '{NEW_BLOCK}' (the state at t = 0)"))
    block = mission.get(NEW_BLOCK)
    for old, new in BLOCK_KEYS.items():
        if _rename_key(block, old, new, lines, (NEW_BLOCK,)):
            was = OLD_BLOCK if found else NEW_BLOCK
            found.append(((was, old), f"'{old}' is now '{new}' (the initial attitude itself, not an error)"))
    for old, new in MISSION_KEYS.items():
        if _rename_key(mission, old, new, lines, ()):
            found.append(((old,), f"'{old}' is now '{new}'"))
    return [((*prefix, *path), message) for path, message in found]


def migrate_campaign(data, lines=None):
    """Rename the old names in a campaign (read from YAML) in place: its inline mission's keys, its
    dispersion paths, sweep parameters and metrics, Sobol metrics, requirements, published columns
    and rare event. Returns [(old key path, message)]."""
    found = []
    if not isinstance(data, dict):
        return found
    if isinstance(data.get("mission"), dict):
        within = None if lines is None else {k[1:]: v for k, v in lines.items() if k[:1] == ("mission",)}
        found += migrate_mission(data["mission"], within, ("mission",))
        if lines is not None:
            lines.update({("mission", *k): v for k, v in within.items()})
    for old, new in PATHS.items():
        if _rename_key(data.get("dispersions"), old, new, lines, ("dispersions",)):
            found.append((("dispersions", old), f"'{old}' is now '{new}'"))

    def text_at(node, key, *path):
        value = node[key]
        if isinstance(value, str) and new_text(value) != value:
            node[key] = new_text(value)
            found.append(((*path, key), f"'{value}' is now '{node[key]}'"))

    sweep = data.get("sweep") if isinstance(data.get("sweep"), dict) else {}
    for i, axis in enumerate(sweep.get("axes") or []):
        if isinstance(axis, dict) and isinstance(axis.get("parameter"), str) and axis["parameter"] in PATHS:
            text_at(axis, "parameter", "sweep", "axes", i)
    for key, holder in (("sweep", sweep), ("sobol", data.get("sobol"))):
        metrics = holder.get("metrics") if isinstance(holder, dict) else None
        for i in range(len(metrics) if isinstance(metrics, list) else 0):
            text_at(metrics, i, key, "metrics")
    requirements = data.get("requirements")
    for i in range(len(requirements) if isinstance(requirements, list) else 0):
        text_at(requirements, i, "requirements")
    for i, entry in enumerate(data.get("published") or [] if isinstance(data.get("published"), list) else []):
        values = entry.get("values") if isinstance(entry, dict) else None
        for old in [key for key in values or {} if isinstance(key, str) and new_text(key) != key]:
            if _rename_key(values, old, new_text(old), lines, ("published", i, "values")):
                found.append((("published", i, "values", old), f"'{old}' is now '{new_text(old)}'"))
    if isinstance(data.get("rare_event"), dict) and "event" in data["rare_event"]:
        text_at(data["rare_event"], "event", "rare_event")
    return found


def warnings_of(found, file, lines, warning_type):
    """One ``warning_type`` (file, line, key path) per renamed name: 'renamed: ...; the old name still loads'."""
    out = []
    for path, message in found:
        line = next((lines[path[:k]] for k in range(len(path), 0, -1) if path[:k] in (lines or {})), None)
        text = f"{message}: renamed by issue 34; the old name still loads, --strict refuses it (docs/interface.md)"
        out.append(warning_type(text, file=file, line=line, path=path))
    return out


def manifest(info):
    """A manifest with its ``columns`` lists in current names."""
    columns = info.get("columns")
    if isinstance(columns, dict):
        renamed = {key: [new_column(c) for c in v] if isinstance(v, list) else v for key, v in columns.items()}
        info = {**info, "columns": renamed}
    return info
