"""The mass a search box left out, by a surrogate of all of C_w: a broad, low mode beyond
the reach of the best log L is seen; a single mode is not flagged."""

from __future__ import annotations

import numpy as np
from scipy.stats import qmc

from susp_bo.calibration.box_mass import share_outside_box
from susp_bo.calibration.settings import CalibrationSettings

SPIKE, SLAB = np.array([0.78, 0.72]), np.array([0.35, 0.4])


def _spike(w: np.ndarray) -> np.ndarray:
    return -0.5 * np.sum(((w - SPIKE) / 0.015) ** 2, axis=1)


def _spike_and_slab(w: np.ndarray) -> np.ndarray:
    """Outside probe, session 25: a spike (sd 0.015) and a slab (sd 0.3) whose peak is 7
    nats lower — beyond ½ χ²₂(0.999) = 6.9 — and which holds 22 % of the mass."""
    slab = -7.0 - 0.5 * np.sum(((w - SLAB) / 0.3) ** 2, axis=1)
    return np.logaddexp(_spike(w), slab)


def _data(log_l) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    design = qmc.Sobol(d=2, scramble=True, rng=np.random.default_rng(1)).random(64)
    near = SPIKE + 0.02 * rng.standard_normal((60, 2))
    x = np.vstack([design, near])
    box = np.array([SPIKE - 0.12, SPIKE + 0.12])  # ± 8 sd of the spike
    draws = SPIKE + 0.015 * rng.standard_normal((4000, 2))  # the box's posterior
    return x, log_l(x), box, draws


def test_a_broad_low_mode_outside_the_box_is_seen() -> None:
    x, y, box, draws = _data(_spike_and_slab)
    share = share_outside_box(x, y, box, draws, CalibrationSettings())
    assert 0.02 <= share <= 0.3  # a lower estimate of the exact 0.22


def test_a_single_mode_leaves_nothing_outside_its_box() -> None:
    x, y, box, draws = _data(_spike)
    assert share_outside_box(x, y, box, draws, CalibrationSettings()) < 0.005
    whole = np.array([[0.0, 0.0], [1.0, 1.0]])
    assert share_outside_box(x, y, whole, draws, CalibrationSettings()) == 0.0
