"""Shared fixtures: the reference vehicle and mission, loaded once per session.

The config dicts are shared; a test that changes one must ``copy.deepcopy`` it first.

``make test`` runs the files on two pytest-xdist workers, a file at a time each (Makefile): the
files that take minutes go first (:data:`LONGEST_FIRST`), so that no worker starts one of them while
the other is about done.
"""

from pathlib import Path

import pytest

from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import pack

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

# the test files of more than a minute on one core (cold kernel cache), about longest first; the
# others follow in pytest's order. Measured with `make test` (pytest --durations): add a file that
# gets long. test_cpu_independence starts at once: its machine-code scan flies every family, which
# in a cold cache compiles them one after the other (minutes; the cache's lock lets one process
# compile at a time), while the other worker flies the first families it compiled
LONGEST_FIRST = [
    "test_cpu_independence.py",
    "test_rare_event.py",
    "test_compare.py",
    "test_subset.py",
    "test_pointing.py",
    "test_knowledge.py",
    "test_allocation.py",
    "test_blending.py",
    "test_cold_gas_fig8.py",
    # a minute or two each (loky and Dask process pools, 10,000 LPs, compiles): not left to the end
    "test_faults.py",
    "test_dask.py",
    "test_lp_allocation.py",
    "test_run.py",
    "test_cli_report_rerun.py",
    "test_report_missions.py",
    "test_sweep.py",
    "test_cli.py",
]


def pytest_collection_modifyitems(items):
    """Files of :data:`LONGEST_FIRST` first, in its order (a stable sort: tests within a file and
    the other files keep their order)."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))


@pytest.fixture(scope="session")
def vehicle_config():
    """configs/vehicles/refex.yaml, validated."""
    return load_vehicle(CONFIGS / "vehicles" / "refex.yaml")


@pytest.fixture(scope="session")
def mission_config():
    """configs/missions/refex-exo.yaml, validated."""
    return load_mission(CONFIGS / "missions" / "refex-exo.yaml")


@pytest.fixture(scope="session")
def inputs(vehicle_config, mission_config):
    """Packed run inputs (config.pack.RunInputs) of the nominal vehicle and mission."""
    return pack(vehicle_config, mission_config)
