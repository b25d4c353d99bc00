"""The scalar stamp helper the bridge's per-message path uses (``stamp_sec_nsec_of``) agrees with the array version
the logger's columns use (``stamp_sec_nsec``), stamp for stamp, including negative stamps, halves of a nanosecond,
seconds beyond int32 (clipped) and non-finite stamps."""

from __future__ import annotations

import numpy as np

from cufund.logs.cdr import stamp_sec_nsec, stamp_sec_nsec_of


def test_scalar_and_array_stamps_agree_on_random_stamps():
    rng = np.random.default_rng(27)
    t = np.concatenate(
        [
            rng.uniform(-100.0, 100.0, 4000),  # around 0, negative included
            rng.uniform(-9e9, 9e9, 2000),  # huge: seconds beyond int32 (clipped), nanoseconds within int64
            np.round(rng.uniform(-1e3, 1e3, 2000) * 1e9) / 1e9 + 0.5e-9,  # near a half nanosecond
            rng.integers(-(2**40), 2**40, 1990) * 1e-9,  # whole nanoseconds
            [0.0, -0.0, 0.5e-9, 1.5e-9, 2.5e-9, -0.5e-9, -1.5e-9, 2**31 - 1e-9, -(2**31), np.nan],
        ]
    )
    assert len(t) == 10_000
    sec, nsec = stamp_sec_nsec(t)
    got = np.array([stamp_sec_nsec_of(float(x)) for x in t])
    np.testing.assert_array_equal(got[:, 0], sec)
    np.testing.assert_array_equal(got[:, 1], nsec)
    assert all(0 <= n < 1_000_000_000 for n in got[:, 1])


def test_scalar_stamp_against_exact_integers():
    # independent of numpy: whole nanoseconds come back exactly; half nanoseconds round to even
    assert stamp_sec_nsec_of(-1.25) == (-2, 750_000_000)
    assert stamp_sec_nsec_of(1.5e-9) == (0, 2) and stamp_sec_nsec_of(2.5e-9) == (0, 2)
    assert stamp_sec_nsec_of(1e10) == (2**31 - 1, 0) and stamp_sec_nsec_of(-1e10) == (-(2**31), 0)
    assert stamp_sec_nsec_of(1e300) == (0, 0)  # the array version: the product overflows to inf, then 0
    assert (
        stamp_sec_nsec_of(float("inf")) == stamp_sec_nsec_of(float("-inf")) == stamp_sec_nsec_of(float("nan")) == (0, 0)
    )
