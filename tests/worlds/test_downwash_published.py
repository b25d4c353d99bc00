"""The downwash model (cufund.worlds.downwash) against a published fit to quadrotor measurements.

Bauersfeld, Muller, Ziegler, Coletti & Scaramuzza, "Robotics meets Fluid Dynamics: a characterization of the induced
airflow below a quadrotor as a turbulent jet", IEEE RA-L 2025, arXiv:2403.13321: over 16 h of flight of six
quadrotors in a large motion-capture hall, the mean flow below a hovering quadrotor is a turbulent jet from about 2.5
vehicle sizes down, and with the hover induced velocity U_H = sqrt(m g / (2 pi rho R^2 n)) (R: propeller radius,
n propellers) and the distance between opposite motors l as scales, one fit describes every vehicle:

    U_c(s) / U_H = B_d / (s / l - s_0),     b(s) / l = S (s / l - s_0),     B_d = 10.11, s_0 = -5.817, S = 0.07668

(U_c: centre-line speed s below the vehicle; b: half-width, where the speed is half U_c). The constants are as
transcribed in a public implementation of the paper's formulas (a helper module "implementing the formulas
described in arXiv:2403.13321", found twice by code search); the paper's own table could not be read here, so they
are not checked against it. They are a fit to measurements, not the measurements themselves.

cufund's model is the textbook round jet (Hussein et al. 1994: B = 5.8, S = 0.094, virtual origin at the vehicle)
carrying the thrust's momentum flux T / rho. Stated agreement, for cu_astro (R = 0.385 arm, l = 2 arms) and the
Crazyflie (R = 23.5 mm, l = 92 mm):

* 10 l to 30 l below (2.0-5.9 m for cu_astro, 0.9-2.6 m for the Crazyflie): the centre-line speed is 0.75-0.99
  times the fit's for cu_astro and 1.06-1.40 times for the Crazyflie; asserted within [0.7, 1.45]. The ratio falls
  with distance: the model's jet decays from the vehicle, the fit's from 5.8 l above it;
* 3 l to 7.5 l below: the model is faster than the fit, 1.1-1.92 times (asserted within [1.05, 2.0]): it
  overstates the near downwash (conservative for separation), where the fit itself begins (2.5 l);
* half-width within 25 % of the fit's from 10 l to 30 l (the model's jet starts narrower and spreads faster).

No published force on a lower vehicle against vertical separation could be read here (Jain et al., ICUAS 2019 and
Kiran, Ayanian & Breuer, RSS 2025 give it in figures and a data set that were not obtained): the thrust-loss half of
the model stays unchecked against measurements (tests/simulator/test_fleet_downwash.py checks it against its formula).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cufund.vehicle import presets
from cufund.worlds.downwash import JET_S, jet_speed

RHO, G = 1.225, 9.81
B_D, S_0, S_FIT = 10.11, -5.817, 0.07668  # Bauersfeld et al. 2025, as transcribed (module doc)

# s / l, then the fit's U_c / U_H = B_d / (s / l - s_0), written out (4 digits)
PUBLISHED_CENTRELINE = [
    (3.0, 1.1466),
    (5.0, 0.9346),
    (7.5, 0.7592),
    (10.0, 0.6392),
    (15.0, 0.4857),
    (20.0, 0.3916),
    (30.0, 0.2823),
]


def _vehicles():
    cu = presets.cu_astro()
    cf = presets.crazyflie()
    return {
        "cu_astro": (cu.mass, 0.385 * cu.arm_length, 2 * cu.arm_length),
        "crazyflie": (cf.mass, 0.0235, 2 * cf.arm_length),
    }


def test_the_table_is_the_published_fit():
    for sl, u in PUBLISHED_CENTRELINE:
        assert B_D / (sl - S_0) == pytest.approx(u, abs=5e-5)


@pytest.mark.parametrize("vehicle", ["cu_astro", "crazyflie"])
def test_centreline_speed_against_the_published_fit(vehicle):
    mass, radius, size = _vehicles()[vehicle]
    thrust = mass * G
    u_h = math.sqrt(thrust / (2 * math.pi * RHO * radius**2 * 4))
    ratios = {}
    for sl, published in PUBLISHED_CENTRELINE:
        model = float(jet_speed(thrust, sl * size, 0.0, radius, RHO)) / u_h
        ratios[sl] = model / published
    far = [r for sl, r in ratios.items() if sl >= 10]
    near = [r for sl, r in ratios.items() if sl < 10]
    assert all(0.7 <= r <= 1.45 for r in far), ratios
    assert all(1.05 <= r <= 2.0 for r in near), ratios
    # the shape differs as stated: the model decays from the vehicle, the fit from 5.8 l above it
    assert ratios[30.0] < ratios[20.0] < ratios[10.0] < ratios[7.5]


def test_half_width_against_the_published_fit():
    for sl in (10.0, 15.0, 20.0, 30.0):
        published = S_FIT * (sl - S_0)
        model = JET_S * sl  # b(s) = S s beyond the near field, in units of l
        assert model / published == pytest.approx(1.0, abs=0.25), sl
    assert JET_S * 3.0 < S_FIT * (3.0 - S_0)  # nearer, the model's jet is narrower


def test_no_speed_laterally_clear_where_the_fit_has_little():
    """Three half-widths off the axis the model is exactly zero; the fit's profile (1 + (sqrt 2 - 1) eta^2)^-2 has
    fallen to 7 % there: the cut-off drops only a small tail."""
    mass, radius, size = _vehicles()["cu_astro"]
    s = 15 * size
    b = JET_S * s
    assert float(jet_speed(mass * G, s, 3.01 * b, radius)) == 0.0
    eta = 3.0
    assert (1 + (math.sqrt(2) - 1) * eta**2) ** -2 < 0.08
    np.testing.assert_allclose(float(jet_speed(mass * G, s, b, radius)) / float(jet_speed(mass * G, s, 0, radius)), 0.5)
