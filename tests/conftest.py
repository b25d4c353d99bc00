import numpy as np
import pytest

import cufund


@pytest.fixture
def crazyflie() -> cufund.QuadrotorParams:
    return cufund.vehicle.presets.crazyflie()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)
