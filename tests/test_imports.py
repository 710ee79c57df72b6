"""The package's import graph has no cycle, counting the imports inside functions (lazy ones) too."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "refexmc"


def module_files():
    """{dotted module name: file} of every module of refexmc."""
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    return modules


def import_graph():
    """{module: the refexmc modules it imports anywhere in its file}."""
    modules = module_files()
    graph = {}
    for name, path in modules.items():
        imported = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").startswith("refexmc"):
                for alias in node.names:  # `from refexmc.x import y`: module refexmc.x.y if there is one
                    submodule = f"{node.module}.{alias.name}"
                    imported.add(submodule if submodule in modules else node.module)
            elif isinstance(node, ast.Import):
                imported.update(alias.name for alias in node.names if alias.name.startswith("refexmc"))
        graph[name] = {module for module in imported if module in modules and module != name}
    return graph


def find_cycle(graph):
    """One import cycle as a list of modules (first repeated last), or None."""
    state = {}  # module -> "open" while on the path, "done" after

    def visit(module, path):
        state[module] = "open"
        for imported in sorted(graph[module]):
            if state.get(imported) == "open":
                return [*path[path.index(imported) :], imported]
            if imported not in state:
                cycle = visit(imported, [*path, imported])
                if cycle:
                    return cycle
        state[module] = "done"
        return None

    for module in sorted(graph):
        if module not in state:
            cycle = visit(module, [module])
            if cycle:
                return cycle
    return None


def test_find_cycle_finds_a_lazy_cycle_and_accepts_a_tree():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_refexmc_has_no_import_cycle():
    graph = import_graph()
    assert "refexmc.campaign.assembly" in graph["refexmc.campaign.dask_backend"]  # the graph sees the imports
    assert "refexmc.campaign.dask_backend" in graph["refexmc.campaign.backends"]  # lazy ones too
    cycle = find_cycle(graph)
    assert cycle is None, f"import cycle: {' -> '.join(cycle)}"


def test_report_campaign_and_cli_never_import_the_core():
    """The report and the campaign read names from the files and the output directory, and fly
    through refexmc.simulate: none of them imports refexmc.core, lazily or not (issue 12)."""
    graph = import_graph()
    offenders = {
        module: sorted(m for m in imported if m == "refexmc.core" or m.startswith("refexmc.core."))
        for module, imported in graph.items()
        if module.startswith(("refexmc.report", "refexmc.campaign")) or module == "refexmc.cli"
    }
    assert not {m: i for m, i in offenders.items() if i}


def test_runs_fan_out_through_joblib_not_a_separate_loky():
    """The design names joblib for fanning out runs: refexmc imports its loky executor
    (``joblib.externals.loky``), never the standalone ``loky`` package, which pyproject.toml does
    not depend on."""
    standalone = {}
    for name, path in module_files().items():
        for node in ast.walk(ast.parse(path.read_text())):
            modules = []
            if isinstance(node, ast.ImportFrom) and node.level == 0:
                modules = [node.module or ""]
            elif isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            if any(module == "loky" or module.startswith("loky.") for module in modules):
                standalone.setdefault(name, []).extend(modules)
    assert not standalone
    from joblib.externals.loky.reusable_executor import _ReusablePoolExecutor

    from refexmc.campaign import pool

    try:
        assert isinstance(pool.executor(1), _ReusablePoolExecutor)
    finally:
        pool.stop()
    pyproject = (PACKAGE.parent / "pyproject.toml").read_text()
    assert '"joblib>=' in pyproject and '"loky' not in pyproject
