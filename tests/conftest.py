"""Shared fixtures: the reference vehicle and mission, loaded once per session.

The config dicts are shared; a test that changes one must ``copy.deepcopy`` it first.
"""

from pathlib import Path

import pytest

from refexmc.config.load import load_mission, load_vehicle
from refexmc.config.pack import pack

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


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
