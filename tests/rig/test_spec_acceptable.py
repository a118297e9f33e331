"""Acceptable domains (maintenance limits) in the rig file: parsed, validated, not fingerprinted."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from susp_bo.rig.catalog import rig_path
from susp_bo.rig.spec import CalibrationParameter, load_rig_spec, parse_rig


def _document() -> dict:
    with rig_path("hst_trailer").open("rb") as handle:
        return tomllib.load(handle)


def _entry(document: dict, name: str) -> dict:
    return next(e for e in document["calibration"]["parameters"] if e["name"] == name)


def test_the_reference_rig_gives_every_parameter_an_acceptable_domain_around_its_nominal() -> None:
    spec = load_rig_spec("hst_trailer")
    for parameter in spec.calibration:
        assert parameter.acceptable is not None, parameter.name
        lo, hi = parameter.acceptable
        assert parameter.lower < lo < parameter.reference < hi < parameter.upper
    damper = next(c for c in spec.calibration if c.name == "secondary_vertical_damping")
    assert damper.acceptable == (28.0e3, 56.0e3)  # 70 % .. 140 % of the nominal 40 kN·s/m


def test_acceptable_is_optional_and_does_not_change_the_fingerprint() -> None:
    document = _document()
    with_limits = parse_rig(document, source="with.toml")
    for entry in document["calibration"]["parameters"]:
        entry.pop("acceptable", None)
    without = parse_rig(document, source="without.toml")
    assert all(c.acceptable is None for c in without.calibration)
    assert with_limits.fingerprint() == without.fingerprint()


@pytest.mark.parametrize(
    ("acceptable", "message"),
    [
        ([50.0e3, 30.0e3], r"lo must be < hi"),
        ([30.0e3, 30.0e3], r"lo must be < hi"),
        ([15.0e3, 50.0e3], r"strictly inside the admissible interval \(15000.0, 80000.0\)"),
        ([20.0e3, 90.0e3], r"strictly inside the admissible interval"),
        ([10.0e3, 50.0e3], r"got \[10000.0, 50000.0\] N·s/m"),
        ([30.0e3], r"expected \[lo, hi\]"),
        ("30e3..50e3", r"expected \[lo, hi\]"),
        ([30.0e3, float("nan")], r"must be finite"),
        ([30.0e3, True], r"must be a number"),
    ],
)
def test_a_bad_acceptable_domain_names_the_file_the_parameter_the_values_and_the_bounds(
    acceptable: object, message: str
) -> None:
    document = _document()
    _entry(document, "secondary_vertical_damping")["acceptable"] = acceptable
    with pytest.raises(ValueError, match=message) as caught:
        parse_rig(document, source="my_rig.toml")
    text = str(caught.value)
    assert text.startswith("my_rig.toml: ")
    assert "secondary_vertical_damping.acceptable" in text
    assert "CalibrationParameter" not in text  # the user wrote a rig file, not a class


def test_a_bad_reference_names_the_parameter_not_a_class() -> None:
    document = _document()
    _entry(document, "secondary_vertical_damping")["reference"] = 1.0e6
    with pytest.raises(ValueError, match=r"secondary_vertical_damping\.reference: got") as caught:
        parse_rig(document, source="my_rig.toml")
    assert "CalibrationParameter" not in str(caught.value)


def test_outside_acceptable_is_the_complement_of_the_closed_band() -> None:
    parameter = CalibrationParameter("x", 0.0, 10.0, 5.0, acceptable=(2.0, 8.0))
    values = np.array([[1.9, 2.0, 5.0], [8.0, 8.1, 0.5]])
    np.testing.assert_array_equal(
        parameter.outside_acceptable(values), [[True, False, False], [False, True, True]]
    )
    with pytest.raises(ValueError, match="no acceptable domain"):
        CalibrationParameter("y", 0.0, 1.0, 0.5).outside_acceptable(values)
