import numpy as np
import pytest

import cufund


@pytest.fixture
def crazyflie() -> cufund.QuadrotorParams:
    return cufund.vehicle.presets.crazyflie()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture(scope="session")
def tunnel_run(tmp_path_factory):
    """The tunnel scenario as shipped, flown once a session into a run folder (log, plots, replay): (run, folder).
    The tests that need the default flight share it (tests/missions/test_tunnel_mission.py, the failsafe tests)."""
    from cufund.scenarios import load_scenario
    from cufund.scenarios.run_folder import run_into_folder

    out = tmp_path_factory.mktemp("tunnel")
    return run_into_folder(load_scenario("tunnel"), out, log=True, replay=True), out
