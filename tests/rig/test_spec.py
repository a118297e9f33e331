"""Rig spec parsing and validation: rigs are data, bad input fails with a clear message."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
import tomli_w
from hypothesis import given, settings
from hypothesis import strategies as st

from susp_bo.rig.catalog import available_rigs, rig_path
from susp_bo.rig.spec import RigSpec, load_rig_spec, parse_rig

PAPER_Q = 7


def _document(name: str = "hst_trailer") -> dict:
    with rig_path(name).open("rb") as handle:
        return tomllib.load(handle)


def test_both_public_rigs_load_with_distinct_data() -> None:
    assert {"hst_trailer", "manchester_benchmark"} <= set(available_rigs())
    hst = load_rig_spec("hst_trailer")
    manchester = load_rig_spec("manchester_benchmark")
    assert hst.topology == manchester.topology == "two_bogie_car"
    assert hst.parameters["carbody_mass"] == 43862.0
    assert manchester.parameters["carbody_mass"] == 32000.0
    assert "Iwnicki" in manchester.reference
    assert hst.fingerprint() != manchester.fingerprint()


def test_reference_rig_has_the_papers_seven_calibration_parameters(reference_spec: RigSpec) -> None:
    assert len(reference_spec.calibration) == PAPER_Q
    bounds = reference_spec.calibration_bounds
    assert bounds.shape == (2, PAPER_Q)
    assert np.all(bounds[0] < reference_spec.calibration_reference)
    assert np.all(reference_spec.calibration_reference < bounds[1])
    values = reference_spec.parameter_values()
    for entry in reference_spec.calibration:
        assert values[entry.name] == entry.reference
        assert entry.unit and entry.description


def test_channels_cover_carbody_and_bogies_vertical_and_lateral(reference_spec: RigSpec) -> None:
    channels = set(reference_spec.channels)
    for place in ("carbody_front", "carbody_mid", "carbody_rear", "bogie_front", "bogie_rear"):
        assert {f"{place}_vertical", f"{place}_lateral"} <= channels


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (
            {"primary_vertical_stifness": 1e6},
            "unknown parameter 'primary_vertical_stifness' (did you mean "
            "'primary_vertical_stiffness'.); known parameters: ",
        ),
        ({"carbody_mass": -1.0}, "carbody_mass: got -1.0; must be > 0"),
        ({"secondary_lateral_stiffness": -5.0}, "must be >= 0"),
        ({"primary_vertical_damping": math.nan}, "must be finite"),
        ({"yaw_damper_damping": math.inf}, "must be finite"),
        ({"primary_vertical_stiffness": 5e6}, "outside the admissible interval"),
        ({"anti_roll_bar_stiffness": 0.5e6}, "outside the admissible interval"),
        ({"carbody_cg_height": -5.0}, "carbody_cg_height: got -5.0; must be > 0"),
        ({"bogie_half_pivot_spacing": 0.5}, "got 0.5 m, not more than bogie_half_wheelbase"),
    ],
)
def test_bad_parameter_values_are_rejected(
    reference_spec: RigSpec, change: dict, message: str
) -> None:
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")):
        reference_spec.with_parameters(change)


def test_parameters_from_vector_checks_length(reference_spec: RigSpec) -> None:
    w = reference_spec.calibration_reference
    assert reference_spec.parameters_from_vector(w)["yaw_damper_damping"] == 4.9e6
    with pytest.raises(ValueError, match="expected q = 7"):
        reference_spec.parameters_from_vector(w[:3])


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0.0, 1.0), min_size=PAPER_Q, max_size=PAPER_Q),
    st.integers(0, PAPER_Q - 1),
    st.floats(1e-6, 1.0),
)
def test_admissible_set_is_exactly_the_box(unit: list[float], index: int, excess: float) -> None:
    spec = load_rig_spec("hst_trailer")
    low, high = spec.calibration_bounds
    w = low + np.array(unit) * (high - low)
    changed = spec.with_parameters(spec.parameters_from_vector(w))
    assert np.allclose([changed.parameters[n] for n in spec.calibration_names], w)
    outside = w.copy()
    outside[index] = high[index] + excess * (high[index] - low[index])
    with pytest.raises(ValueError, match="outside the admissible interval"):
        spec.with_parameters(spec.parameters_from_vector(outside))


def test_fingerprint_is_stable_and_content_sensitive(reference_spec: RigSpec) -> None:
    again = load_rig_spec("hst_trailer")
    assert again.fingerprint() == reference_spec.fingerprint()
    changed = reference_spec.with_parameters({"secondary_vertical_damping": 41e3})
    assert changed.fingerprint() != reference_spec.fingerprint()


def test_round_trip_through_a_written_toml_file(tmp_path) -> None:
    document = _document()
    document["rig"]["name"] = "copy"
    path = tmp_path / "copy.toml"
    path.write_bytes(tomli_w.dumps(document).encode())
    spec = load_rig_spec(path)
    assert spec.name == "copy"
    assert spec.parameters == load_rig_spec("hst_trailer").parameters


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.update(suspension={"x": 1.0}), r"top level: suspension: unknown key"),
        (lambda d: d["primary"].pop("vertical_stiffness"), "missing parameters"),
        (lambda d: d["sensors"][0].update(direction="longitudinal"), "direction"),
        (
            lambda d: d["sensors"][0].update(body="wheelset_1"),
            r"\[\[sensors\]\] entry 1 \('carbody_front_vertical'\): body 'wheelset_1' is not "
            r"allowed; allowed bodies: carbody, bogie_front, bogie_rear",
        ),
        (lambda d: d["sensors"][2].update(body="roof"), r"entry 3 .*: body 'roof' is not allowed"),
        (lambda d: d["simulation"].update(sample_rate_hz=300.0), "integer multiple"),
        (lambda d: d["simulation"].update(speed_m_s=0.0), "speed_m_s"),
        (lambda d: d["spectrum"].update(f_min_hz=0.1), "f_min_hz"),
        (
            lambda d: d["calibration"]["parameters"][0].update(reference=1.0e6),
            "differs from the rig value",
        ),
        (lambda d: d["calibration"]["parameters"][0].update(lower=2e6), "lower"),
        (
            lambda d: d["calibration"]["parameters"][1].update(name="nonexistent"),
            "not a named parameter",
        ),
        (
            lambda d: d.update(effects={"no_such_effect": {}}),
            r"\[effects.no_such_effect\]: unknown effect 'no_such_effect'; allowed effects: "
            r".*carbody_bending",
        ),
        (
            lambda d: d.update(effects={"carbody_bendin": {"enabled": False}}),
            r"unknown effect 'carbody_bendin' \(did you mean 'carbody_bending'\?\)",
        ),
        (
            lambda d: d["simulation"].update(speed_m_s=5.0),
            r"\[simulation\] speed_m_s: 5 m/s is not allowed: below the minimum speed 7\.91",
        ),
        (
            lambda d: d["simulation"].update(time_step_s=0.01),
            r"\[simulation\] time_step_s: 0\.01 s is too long for rig 'hst_trailer'",
        ),
    ],
)
def test_invalid_rig_files_fail_with_a_named_field(edit, message) -> None:
    """Also what used to pass the load and fail only once simulations ran (a sensor on
    no body, an unknown effect) or diverge (a speed the time step cannot simulate)."""
    document = _document()
    edit(document)
    with pytest.raises(ValueError, match=message) as raised:
        parse_rig(document, source="edited.toml")
    assert str(raised.value).startswith("edited.toml: ")


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (
            lambda d: d["carbody"].update(cg_hieght=1.9),
            r"\[carbody\] cg_hieght: unknown key \(did you mean 'cg_height'\?\)",
        ),
        (
            lambda d: d["simulation"].update(track_qualty="low"),
            r"\[simulation\] track_qualty: unknown key \(did you mean 'track_quality'\?\)",
        ),
        (
            lambda d: d["spectrum"].update(f_max=20.0),
            r"\[spectrum\] f_max: unknown key \(did you mean 'f_max_hz'\?\)",
        ),
        (
            lambda d: d["calibration"]["parameters"][0].update(units="N/m"),
            r"primary_vertical_stiffness: units: unknown key \(did you mean 'unit'\?\)",
        ),
        (
            lambda d: d["calibration"]["parameters"][0].pop("upper"),
            r"primary_vertical_stiffness: missing upper",
        ),
        (
            lambda d: d["sensors"][0].update(positon_m=[0, 0, 0]),
            r"\[\[sensors\]\] entry 1: positon_m: unknown key \(did you mean 'position_m'\?\)",
        ),
        (lambda d: d["rig"].update(nmae="x"), r"\[rig\] nmae: unknown key \(did you mean 'name'"),
        (lambda d: d["calibration"].update(parameter=[]), r"did you mean 'parameters'"),
        (lambda d: d.update(wheelsets={"mass": 1.0}), r"did you mean 'wheelset'"),
    ],
)
def test_unknown_keys_anywhere_are_errors_with_a_hint(edit, message) -> None:
    """A typo never becomes a new parameter: `cg_hieght = 1.9` used to pass silently."""
    document = _document()
    edit(document)
    with pytest.raises(ValueError, match=message):
        parse_rig(document, source="typo.toml")


def test_acceptable_key_and_optional_parameters_are_allowed() -> None:
    document = _document()
    document["calibration"]["parameters"][0]["acceptable"] = [0.9e6, 1.5e6]
    spec = parse_rig(document)
    assert spec.calibration_names[0] == "primary_vertical_stiffness"
    assert spec.parameters["wheelset_spin_inertia"] == 123.0  # optional key of [wheelset]


def test_invalid_toml_names_the_file_and_line(tmp_path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text('[rig]\nname = "x"\n[carbody\nmass = 1.0\n')
    with pytest.raises(ValueError, match=r"broken.toml: not valid TOML .*line 3"):
        load_rig_spec(path)


def test_a_rig_file_that_is_not_utf8_text_is_named(tmp_path) -> None:
    path = tmp_path / "binary.toml"
    path.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValueError, match=r"binary\.toml: not a UTF-8 text file") as raised:
        load_rig_spec(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_effects_table_is_parsed_for_the_registry() -> None:
    document = _document()
    document["effects"] = {"carbody_bending": {"enabled": False, "frequency_hz": 9.0}}
    spec = parse_rig(document)
    assert spec.effects == {"carbody_bending": {"enabled": False, "frequency_hz": 9.0}}


def test_a_repeated_calibration_parameter_is_named_not_the_whole_list() -> None:
    document = _document()
    entries = document["calibration"]["parameters"]
    entries.append(dict(entries[2]))  # secondary_vertical_stiffness, a second time
    with pytest.raises(ValueError) as raised:
        parse_rig(document)
    message = str(raised.value)
    assert "'secondary_vertical_stiffness' is listed more than once" in message
    assert "primary_vertical_damping" not in message  # not the whole list


def test_no_sensors_is_told_apart_from_a_repeated_sensor() -> None:
    document = _document()
    document["sensors"] = []
    with pytest.raises(ValueError, match=r"\[\[sensors\]\]: none given; expected at least one"):
        parse_rig(document)
    document = _document()
    document["sensors"].append(dict(document["sensors"][1]))
    repeated = document["sensors"][1]["name"]
    with pytest.raises(ValueError, match=rf"sensor name {repeated!r} is given more than once"):
        parse_rig(document)


@pytest.mark.parametrize("name", ["", "  "])
def test_a_sensor_without_a_name_is_refused(name: object) -> None:
    document = _document()
    document["sensors"][1]["name"] = name
    with pytest.raises(ValueError, match=rf"\[\[sensors\]\] entry 2: name {name!r} is not allowed"):
        parse_rig(document)
