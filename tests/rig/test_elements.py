"""Force laws of the suspension elements against their closed forms."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from susp_bo.rig.elements import (
    bilinear_force,
    bilinear_velocity,
    dead_band_force,
    dead_band_slope,
)


def test_bilinear_damper_matches_the_published_characteristic() -> None:
    # primary vertical damper of the reference car: 13 kN·s/m, 6.5 beyond 0.01 m/s
    v = np.array([-0.11, -0.01, 0.0, 0.005, 0.01, 0.11])
    f = bilinear_force(v, 13e3, 0.5, 0.01)
    expected = np.array([-(130 + 650), -130.0, 0.0, 65.0, 130.0, 130 + 650])
    np.testing.assert_allclose(f, expected, rtol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.floats(-2.0, 2.0), st.floats(1e3, 1e7), st.floats(0.01, 1.0), st.floats(1e-3, 0.5))
def test_bilinear_velocity_inverts_the_force(v: float, c: float, ratio: float, knee: float) -> None:
    force = bilinear_force(np.array([v]), c, ratio, knee)
    np.testing.assert_allclose(bilinear_velocity(force, c, ratio, knee), [v], atol=1e-12)


def test_dead_band_is_silent_inside_the_gap_and_stiff_outside() -> None:
    k, gap, smooth = 2e6, 0.02, 0.002
    inside = dead_band_force(np.array([-0.01, 0.0, 0.01]), k, gap, smooth)
    assert np.all(np.abs(inside) < k * smooth * 0.01)
    outside = dead_band_force(np.array([0.05, -0.05]), k, gap, smooth)
    np.testing.assert_allclose(outside, [k * 0.03, -k * 0.03], rtol=1e-6)
    h = 1e-7
    numeric = (
        dead_band_force(np.array([h]), k, gap, smooth)
        - dead_band_force(np.array([-h]), k, gap, smooth)
    ) / (2 * h)
    np.testing.assert_allclose(numeric, dead_band_slope(k, gap, smooth), rtol=1e-5)
