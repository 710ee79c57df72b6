"""The package's import graph: no cycle, and no import from a lower layer to a higher one
(:data:`LAYERS`), counting the imports inside functions (lazy ones) too."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "refexmc"

# The way a campaign file takes, bottom to top: a module imports only from its own layer or a
# lower one. Each entry is a module or a subpackage (every module under it; ``refexmc`` itself is
# the package's __init__ only); every module must sit in one (a new module of the package's top
# level is placed here on purpose).
LAYERS = (
    ("refexmc", "refexmc._jit"),  # the version; the one place of JIT settings
    ("refexmc.core",),  # numba kernels on plain arrays (style.md 1)
    # shared arithmetic below both config and campaign: small matrices, correctly rounded
    # functions, the distributions' draws and supports, binomial intervals
    ("refexmc.smallmatrix", "refexmc.crmath", "refexmc.distributions", "refexmc.binomial"),
    ("refexmc.config",),  # YAML -> validated campaign (every check, in one pass) -> packed inputs
    # one run through the core (configured requirements' columns); runs on a GPU (numba-cuda)
    ("refexmc.simulate", "refexmc.simulate_cuda"),
    ("refexmc.campaign",),  # sampling, seeding, backends, storage, studies
    ("refexmc.report",),  # statistics, verdicts, figures of a stored output
    ("refexmc.cli",),  # the click layer over all of them
)


def module_files(package=PACKAGE):
    """{dotted module name: file} of every module of the package at ``package``."""
    modules = {}
    for path in package.rglob("*.py"):
        parts = path.relative_to(package.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        modules[name] = path
    return modules


def _absolute(node, module, is_package):
    """The absolute module name of an ``ImportFrom`` in ``module`` (a relative one resolved)."""
    if node.level == 0:
        return node.module or ""
    base = module.split(".")
    base = base[: len(base) - node.level + (1 if is_package else 0)]
    return ".".join([*base, node.module] if node.module else base)


def _imported_names(tree, module, is_package, root):
    """The ``root`` modules (and ``module.attribute`` candidates) a parsed file imports anywhere:
    ``import``, ``from ... import`` (relative too), ``importlib.import_module("...")``."""
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            base = _absolute(node, module, is_package)
            if base == root or base.startswith(root + "."):
                names.update((base, f"{base}.{alias.name}") for alias in node.names)
        elif isinstance(node, ast.Import):
            names.update((alias.name, None) for alias in node.names if alias.name.split(".")[0] == root)
        elif (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr == "import_module"
            and node.args
            and isinstance(node.args[0], ast.Constant)
            and str(node.args[0].value).split(".")[0] == root
        ):
            names.add((node.args[0].value, None))
    return names


def import_graph(package=PACKAGE):
    """{module: the modules of the package it imports anywhere in its file}."""
    modules = module_files(package)
    root = package.name
    graph = {}
    for name, path in modules.items():
        imported = set()
        tree = ast.parse(path.read_text())
        for base, submodule in _imported_names(tree, name, path.name == "__init__.py", root):
            # `from refexmc.x import y`: module refexmc.x.y if there is one
            imported.add(submodule if submodule in modules else base)
        graph[name] = {module for module in imported if module in modules and module != name}
    return graph


def layer_of(module, layers=LAYERS):
    """Index of the layer ``module`` sits in (the entry that is it or a subpackage above it), or None."""
    for index, entries in enumerate(layers):
        for entry in entries:
            if module == entry or ("." in entry and module.startswith(entry + ".")):
                return index
    return None


def layer_violations(graph, layers=LAYERS):
    """['a -> b (layer i imports layer j > i)'] for each import upward, and each module in no layer."""
    problems = [f"{module}: in no layer of LAYERS" for module in sorted(graph) if layer_of(module, layers) is None]
    for module in sorted(graph):
        low = layer_of(module, layers)
        for imported in sorted(graph[module]):
            high = layer_of(imported, layers)
            if low is not None and high is not None and high > low:
                problems.append(f"{module} -> {imported} (layer {low} imports layer {high})")
    return problems


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


def test_no_module_imports_from_a_higher_layer():
    """config validates a campaign without climbing into campaign; campaign never reads report
    (issue 34 point 9); the core, the shared arithmetic and simulate stay below what uses them."""
    graph = import_graph()
    assert "refexmc.campaign.saltelli" in graph["refexmc.campaign.sampling"]  # the graph sees the imports
    assert layer_of("refexmc.config.load") == 3 and layer_of("refexmc.distributions") == 2
    violations = layer_violations(graph)
    assert not violations, "imports against the layers:\n" + "\n".join(violations)


def test_a_planted_upward_import_is_found(tmp_path):
    """A lazy import of report from config, a relative one from campaign, an importlib one from the
    core, and a module in no layer: each one is named (the check can fail)."""
    package = tmp_path / "refexmc"
    files = {
        "__init__.py": "",
        "core/__init__.py": "",
        "core/kernel.py": "import importlib\n\ndef f():\n    importlib.import_module('refexmc.config.load')\n",
        "config/__init__.py": "",
        "config/load.py": "from refexmc import distributions\n\n\ndef check():\n    from refexmc.report import stats\n",
        "distributions.py": "import math\n",
        "campaign/__init__.py": "",
        "campaign/sequential.py": "from ..report.stats import clopper_pearson\nfrom . import sampling\n",
        "campaign/sampling.py": "from refexmc.config import load\n",
        "report/__init__.py": "",
        "report/stats.py": "from refexmc.campaign import sampling\n",
        "stray.py": "",
    }
    for name, text in files.items():
        (package / name).parent.mkdir(parents=True, exist_ok=True)
        (package / name).write_text(text)
    assert layer_violations(import_graph(package)) == [
        "refexmc.stray: in no layer of LAYERS",
        "refexmc.campaign.sequential -> refexmc.report.stats (layer 5 imports layer 6)",
        "refexmc.config.load -> refexmc.report.stats (layer 3 imports layer 6)",
        "refexmc.core.kernel -> refexmc.config.load (layer 1 imports layer 3)",
    ]


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
