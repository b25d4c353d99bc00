"""cufund.mapping.edt against scipy.ndimage.distance_transform_edt (an independent exact EDT)."""

import numpy as np
import pytest
from scipy import ndimage

from cufund import mapping as esdf


def scipy_edt(occ, sampling):
    return ndimage.distance_transform_edt(~occ, sampling=sampling)


def random_occupancy(rng, shape, density):
    occ = rng.random(shape) < density
    occ.flat[rng.integers(occ.size)] = True  # at least one site
    return occ


@pytest.mark.parametrize("shape", [(31, 27, 19), (64, 5, 40), (2, 50, 33), (45, 61)])
@pytest.mark.parametrize("density", [0.002, 0.05, 0.5])
def test_isotropic_equals_scipy_exactly(shape, density):
    rng = np.random.default_rng(abs(hash((shape, density))) % 2**32)
    occ = random_occupancy(rng, shape, density)
    np.testing.assert_array_equal(esdf.edt(occ), scipy_edt(occ, None))


@pytest.mark.parametrize(
    ("shape", "voxel_size"),
    [((40, 33, 12), (0.1, 0.1, 0.25)), ((7, 90, 31), (0.05, 0.3, 0.17)), ((70, 23), (2.5, 0.4)), ((55, 1, 20), 0.2)],
)
def test_anisotropic_equals_scipy_to_rounding(shape, voxel_size):
    rng = np.random.default_rng(7)
    for density in (0.003, 0.1):
        occ = random_occupancy(rng, shape, density)
        ref = scipy_edt(occ, voxel_size)
        np.testing.assert_allclose(esdf.edt(occ, voxel_size=voxel_size), ref, rtol=1e-13, atol=0)
        np.testing.assert_allclose(esdf.edt(occ, voxel_size=voxel_size, dtype=np.float32), ref, rtol=3e-7, atol=0)


def test_signed_is_outside_minus_inside():
    rng = np.random.default_rng(3)
    occ = random_occupancy(rng, (30, 20, 25), 0.4)
    h = (0.1, 0.2, 0.15)
    got = esdf.edt(occ, voxel_size=h, signed=True)
    np.testing.assert_allclose(got, scipy_edt(occ, h) - scipy_edt(~occ, h), rtol=1e-13, atol=0)
    assert np.all(got[occ] < 0) and np.all(got[~occ] > 0)


def test_thread_count_does_not_change_the_result():
    occ = random_occupancy(np.random.default_rng(5), (50, 40, 30), 0.01)
    one = esdf.edt(occ, voxel_size=(0.1, 0.1, 0.2), nthreads=1)
    np.testing.assert_array_equal(one, esdf.edt(occ, voxel_size=(0.1, 0.1, 0.2), nthreads=3))


def test_accepts_integer_and_non_contiguous_input():
    occ = random_occupancy(np.random.default_rng(11), (20, 30, 16), 0.05)
    ref = esdf.edt(occ)
    np.testing.assert_array_equal(esdf.edt(occ.astype(np.int32) * 7), ref)
    big = np.zeros((40, 30, 32), dtype=bool)
    big[::2, :, ::2] = occ
    np.testing.assert_array_equal(esdf.edt(big[::2, :, ::2]), ref)


def test_empty_and_full_grids():
    assert np.all(esdf.edt(np.zeros((4, 5, 6), dtype=bool)) == np.inf)
    np.testing.assert_array_equal(esdf.edt(np.ones((4, 5), dtype=bool)), np.zeros((4, 5)))
    assert np.all(esdf.edt(np.ones((3, 3), dtype=bool), signed=True) == -np.inf)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"occupied": np.zeros((3, 3), dtype=float)}, "occupied must be a boolean"),
        ({"occupied": np.zeros((2, 2, 2, 2), dtype=bool)}, r"1-D, 2-D or 3-D array, got shape \(2, 2, 2, 2\)"),
        ({"occupied": np.zeros((0, 3), dtype=bool)}, "must not be empty"),
        ({"voxel_size": 0.0}, "voxel_size must be finite and > 0"),
        ({"voxel_size": (0.1, np.nan, 0.1)}, "voxel_size must be finite and > 0"),
        ({"voxel_size": (0.1, 0.2)}, r"voxel_size must have shape \(3,\), got \(2,\)"),
        ({"nthreads": -1}, "nthreads must be an integer >= 0"),
        ({"dtype": np.int32}, "dtype must be float32 or float64"),
        ({"signed": "yes"}, "signed must be a bool"),
    ],
)
def test_bad_input_raises_clear_errors(kwargs, message):
    args = {"occupied": np.zeros((3, 4, 5), dtype=bool)} | kwargs
    with pytest.raises(ValueError, match=message):
        esdf.edt(**args)
