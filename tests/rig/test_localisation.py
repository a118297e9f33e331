"""Localisation of single-component failures by the shipped sensors (linearised model)."""

from __future__ import annotations

import numpy as np
import pytest

from susp_bo.rig.linear import LinearisedRig
from susp_bo.rig.localisation import (
    UNKNOWN_TRACK_SCATTER_DB,
    FailureSignatures,
    failure_signatures,
    format_separations,
    format_signatures,
    pair_separation,
    single_component_failures,
    verdict,
)
from susp_bo.rig.spec import RigSpec

Y, S, P = "yaw_damper_damping@", "secondary_vertical_damping@", "primary_vertical_damping@"


@pytest.fixture(scope="module")
def signatures(reference_spec: RigSpec) -> FailureSignatures:
    """Every yaw, secondary vertical and primary vertical damper at 50 %, one at a time."""
    return failure_signatures(
        LinearisedRig(reference_spec).spectra, single_component_failures(reference_spec)
    )


def test_the_failures_are_every_component_at_half_its_nominal(
    signatures: FailureSignatures,
) -> None:
    assert len(signatures.failures) == 4 + 4 + 8
    assert signatures.change_db.shape == (16, 10, len(signatures.frequencies_hz))
    failure = signatures.failures[signatures.index(Y + "bogie_rear_right")]
    assert failure.value == 0.5 * 4.9e6
    assert failure.label == "yaw_damper_damping@bogie_rear_right 50%"
    text = format_signatures(signatures)
    assert "cb_f_v" in text and "bg_r_l = bogie_rear_lateral" in text


@pytest.mark.parametrize(
    ("left", "right"),
    [
        (Y + "bogie_front_left", Y + "bogie_front_right"),
        (S + "bogie_rear_left", S + "bogie_rear_right"),
        (P + "wheelset_2_left", P + "wheelset_2_right"),
    ],
)
def test_left_and_right_look_the_same_from_the_carbody(
    signatures: FailureSignatures, left: str, right: str
) -> None:
    # mirror symmetry: the carbody sensors sit on the centre line, so a left and a right
    # failure give the same carbody spectra; only the (left-side) bogie sensors differ
    carbody = pair_separation(signatures, left, right, "carbody")
    assert carbody.cosine > 0.9999, carbody
    assert carbody.verdict == "not localisable"
    mask = signatures.channel_mask("carbody")
    np.testing.assert_allclose(
        signatures.change_db[signatures.index(left)][mask],
        signatures.change_db[signatures.index(right)][mask],
        atol=1e-9,
    )


def test_front_and_rear_yaw_dampers_are_told_apart_by_the_bogie_frames(
    signatures: FailureSignatures,
) -> None:
    front, rear = Y + "bogie_front_left", Y + "bogie_rear_left"
    bogie = pair_separation(signatures, front, rear, "bogie")
    assert bogie.cosine < 0.5, bogie  # different directions: the bogie frames localise them
    rms = signatures.rms_db()
    lateral = [signatures.channels.index(f"bogie_{b}_lateral") for b in ("front", "rear")]
    # each bogie's lateral sensor sees its own bogie's yaw damper more than the other's
    assert rms[signatures.index(front), lateral[0]] > 2 * rms[signatures.index(rear), lateral[0]]
    assert rms[signatures.index(rear), lateral[1]] > 2 * rms[signatures.index(front), lateral[1]]
    # ...given spectra that scatter little (a measured track: sensor noise only)
    assert pair_separation(signatures, front, rear, "bogie", 0.05).verdict == "localisable"
    # with the track unknown (~1.5 dB scatter) a yaw damper at 50 % is not even detected
    unknown = signatures.detection_z(UNKNOWN_TRACK_SCATTER_DB)
    assert unknown[signatures.index(front)] < 2.0
    assert pair_separation(signatures, front, rear).verdict == "not localisable"


def test_left_and_right_yaw_damper_of_one_bogie_are_not_localisable_on_unknown_track(
    signatures: FailureSignatures,
) -> None:
    pair = pair_separation(signatures, Y + "bogie_front_left", Y + "bogie_front_right")
    assert pair.verdict == "not localisable" and pair.sd_inflation > 5.0, pair
    assert pair.z < 0.5 and pair.cosine > 0.98
    assert "not localisable" in format_separations([pair])


def test_a_secondary_vertical_damper_side_is_seen_by_the_bogie_sensor_on_that_side(
    signatures: FailureSignatures,
) -> None:
    rms = signatures.rms_db()
    sensor = signatures.channels.index("bogie_front_vertical")  # left side of the frame
    left, right = (signatures.index(S + f"bogie_front_{side}") for side in ("left", "right"))
    assert rms[left, sensor] > 1.0 > 0.3 > rms[right, sensor]
    pair = pair_separation(signatures, S + "bogie_front_left", S + "bogie_front_right")
    assert pair.verdict != "not localisable", pair


def test_a_per_band_scatter_weights_the_bands(signatures: FailureSignatures) -> None:
    sigma = np.full(signatures.change_db.shape[1:], 1.5)
    a, b = Y + "bogie_front_left", Y + "bogie_rear_left"
    assert pair_separation(signatures, a, b, scatter_db=sigma) == pair_separation(
        signatures, a, b, scatter_db=1.5
    )
    sigma[signatures.channel_mask("carbody")] = 1e6  # carbody channels carry nothing
    assert pair_separation(signatures, a, b, scatter_db=sigma).cosine == pytest.approx(
        pair_separation(signatures, a, b, "bogie").cosine, abs=1e-6
    )


def test_verdicts_and_errors(reference_spec: RigSpec, signatures: FailureSignatures) -> None:
    assert verdict(1.9) == verdict(float("nan")) == "not localisable"
    assert verdict(2.0) == verdict(4.9) == "weak"
    assert verdict(5.0) == "localisable"
    with pytest.raises(ValueError, match="'carbody_mass'; it has no per-component form"):
        single_component_failures(reference_spec, ("carbody_mass",))
    with pytest.raises(ValueError, match=r"fraction: got 0\.0"):
        single_component_failures(reference_spec, fraction=0.0)
    with pytest.raises(KeyError, match="no failure of"):
        signatures.index("yaw_damper_damping")
    with pytest.raises(ValueError, match="no channel starts with it"):
        signatures.channel_mask("wheelset")
    with pytest.raises(ValueError, match="must be > 0 dB everywhere"):
        pair_separation(signatures, Y + "bogie_front_left", Y + "bogie_rear_left", "all", 0.0)
