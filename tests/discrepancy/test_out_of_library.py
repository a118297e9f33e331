"""Out-of-library modifications: rig file and spec agree; sensor models against exact answers."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from susp_bo.discrepancy.effects import EFFECTS
from susp_bo.discrepancy.out_of_library import (
    MODIFICATIONS,
    bracket_response,
    get_modification,
)
from susp_bo.rig.catalog import rig_path
from susp_bo.rig.spec import load_rig_spec, parse_rig


@pytest.mark.parametrize("name", sorted(MODIFICATIONS))
def test_the_rig_file_and_the_spec_are_changed_alike(name: str) -> None:
    change = get_modification(name)
    document = tomllib.loads(rig_path("hst_trailer").read_text())
    from_file = parse_rig(change.apply_document(document))
    from_spec = change.apply_spec(load_rig_spec("hst_trailer"))
    assert from_file.parameters == from_spec.parameters
    assert from_file.sensors == from_spec.sensors
    assert from_file.effects == {} or not any(e in from_file.effects for e in EFFECTS)
    assert not any(p.startswith(tuple(EFFECTS)) for p in change.parameters)  # not the library


def test_at_least_three_kinds_none_from_the_library() -> None:
    kinds = {
        "contact": any("contact" in p for m in MODIFICATIONS.values() for p in m.parameters),
        "element": any("stiffness" in p for m in MODIFICATIONS.values() for p in m.parameters),
        "sensor": any(m.changes_signals or m.sensor_positions for m in MODIFICATIONS.values()),
    }
    assert all(kinds.values()), kinds


@pytest.mark.parametrize("zeta", [0.05, 0.1, 0.3])
def test_bracket_transmissibility_at_resonance_and_far_below(zeta: float) -> None:
    rate, n = 100.0, 4000  # 40 s: whole periods of 6 Hz and 0.5 Hz
    t = np.arange(n) / rate
    amplitude = lambda x: math.sqrt(2.0 * np.mean(x**2))  # noqa: E731 - whole periods: exact
    at = bracket_response(np.sin(2 * math.pi * 6.0 * t), rate, 6.0, zeta)
    assert amplitude(at) == pytest.approx(math.sqrt(1 + 4 * zeta**2) / (2 * zeta), rel=1e-6)
    low = bracket_response(np.sin(2 * math.pi * 0.5 * t), rate, 6.0, zeta)
    r = 0.5 / 6.0
    exact = math.hypot(1, 2 * zeta * r) / math.hypot(1 - r**2, 2 * zeta * r)
    assert amplitude(low) == pytest.approx(exact, rel=1e-6)


def test_a_rolled_sensor_mixes_in_the_vertical_channel() -> None:
    change = get_modification("sensor_rolled")
    channels = ("bogie_front_vertical", "bogie_front_lateral", "other")
    signals = np.array([[1.0, 2.0], [0.5, -1.0], [3.0, 3.0]])
    out = change.apply_signals(signals, channels, 100.0)
    theta = math.radians(20.0)
    np.testing.assert_allclose(out[1], math.cos(theta) * signals[1] + math.sin(theta) * signals[0])
    np.testing.assert_array_equal(out[[0, 2]], signals[[0, 2]])


def test_an_unknown_kind_is_refused_with_the_known_ones() -> None:
    with pytest.raises(ValueError, match="high_conicity"):
        get_modification("bent_axle")
