"""Track design: evaluation against closed forms, line files, and bad input refused early."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from susp_bo.rig.design import (
    GRAVITY_M_S2,
    RAIL_CENTRES_M,
    DesignError,
    TrackDesign,
    balancing_cant_m,
    design_specific_force,
)
from susp_bo.rig.line_file import design_from_segments, load_line

CURVE = [
    {"type": "tangent", "length_m": 100.0},
    {"type": "transition", "length_m": 100.0},
    {
        "type": "curve",
        "length_m": 500.0,
        "radius_m": 2000.0,
        "cant_mm": 100.0,
        "direction": "left",
        "gradient_permille": 5.0,
    },
    {"type": "transition", "length_m": 100.0},
    {"type": "tangent", "length_m": 300.0},
]


def test_clothoid_and_circle_match_their_closed_forms() -> None:
    design = design_from_segments(CURVE)
    kappa = 1.0 / 2000.0
    # clothoid: κ = κ_c u / L, heading κ_c u² / 2L, lateral offset κ_c u³ / 6L
    u = np.array([0.0, 25.0, 50.0, 100.0])
    s = 100.0 + u
    np.testing.assert_allclose(design.curvature(s), kappa * u / 100.0, atol=1e-15)
    np.testing.assert_allclose(design.heading_rad(s), kappa * u**2 / 200.0, atol=1e-15)
    np.testing.assert_allclose(design.lateral_m(s), kappa * u**3 / 600.0, atol=1e-12)
    np.testing.assert_allclose(design.cant(s), -0.1 * u / 100.0, atol=1e-15)  # right rail up
    # in the circle the heading grows at κ and the offset from the tangent at 200 m is κ x²/2
    x = np.array([0.0, 40.0, 200.0])
    offset = design.lateral_m(200.0 + x) - design.lateral_m(200.0) - design.heading_rad(200.0) * x
    np.testing.assert_allclose(offset, kappa * x**2 / 2.0, rtol=1e-12, atol=1e-15)
    assert design.grade(400.0)[0] == pytest.approx(0.005)
    assert design.roll_rad(400.0) == pytest.approx(-math.asin(0.1 / RAIL_CENTRES_M))
    assert design.end_m == pytest.approx(1100.0)


def test_uncompensated_lateral_acceleration_and_balancing_cant() -> None:
    speed, radius = 83.33, 7000.0
    cant = balancing_cant_m(radius, speed)
    assert 0.0 < cant < 0.180
    design = design_from_segments(
        [
            {
                "type": "curve",
                "length_m": 100.0,
                "radius_m": radius,
                "cant_mm": cant * 1000,
                "direction": "right",
            }
        ]
    )
    lateral, vertical = design_specific_force(design, np.array([50.0]), speed)
    assert abs(lateral[0]) < 1e-12
    assert vertical[0] > 0  # cant and curve press the vehicle into the track
    tilted = design_from_segments(
        [
            {
                "type": "curve",
                "length_m": 100.0,
                "radius_m": 2000.0,
                "cant_mm": 60.0,
                "direction": "left",
            }
        ]
    )
    lateral, _ = design_specific_force(tilted, np.array([50.0]), speed)
    textbook = speed**2 / 2000.0 - GRAVITY_M_S2 * 0.060 / RAIL_CENTRES_M  # V²/R − g φ
    assert lateral[0] == pytest.approx(textbook, rel=2e-3)


def test_a_curve_without_transition_is_a_step() -> None:
    design = design_from_segments(
        [
            {"type": "tangent", "length_m": 50.0},
            {"type": "curve", "length_m": 50.0, "radius_m": 1000.0, "direction": "right"},
        ]
    )
    assert design.curvature(49.999) == 0.0
    assert design.curvature(50.0) == pytest.approx(-1e-3)
    assert design.curvature(50.001) == pytest.approx(-1e-3)


@pytest.mark.parametrize(
    ("segment", "message"),
    [
        ({"radius_m": 120.0}, "below the minimum 150 m"),
        ({"cant_mm": 200.0}, "above the allowed maximum 180 mm"),
        ({"cant_mm": 0.15}, "suggests metres given as millimetres"),
        ({"gradient_permille": 0.012}, "a fraction given as per mille"),
        ({"gradient_permille": 45.0}, "above the maximum 40 per mille"),
        ({"direction": "up"}, "allowed 'left'"),
        ({"cant_m": 0.1}, "cant_mm"),
        ({"radius": 3000.0}, "unknown key"),
        ({"length_m": -5.0}, "must be > 0 m"),
        ({"length_m": 1e300}, r"length_m: got 1e\+300 m; above the maximum 2e\+07 m"),
    ],
)
def test_bad_segments_are_refused_with_the_value_and_the_limit(
    segment: dict[str, object], message: str
) -> None:
    curve = {"type": "curve", "length_m": 100.0, "radius_m": 3000.0, "direction": "left"}
    curve.update(segment)
    with pytest.raises(DesignError, match=message) as error:
        design_from_segments([curve], source="line.toml")
    assert "line.toml: segment 1" in str(error.value)


def test_sampled_records_are_checked_for_unit_slips_and_limits() -> None:
    s = np.array([0.0, 100.0])
    with pytest.raises(DesignError, match="suggests millimetres"):
        TrackDesign(s, np.zeros(2), np.array([0.0, 150.0]), np.zeros(2), source="run.h5")
    with pytest.raises(DesignError, match="looks like a radius"):
        TrackDesign(s, np.array([0.0, 2000.0]), np.zeros(2), np.zeros(2))
    with pytest.raises(DesignError, match=r"radius 100\.0 m is below"):
        TrackDesign(s, np.array([0.0, 0.01]), np.zeros(2), np.zeros(2))
    with pytest.raises(DesignError, match="non-decreasing"):
        TrackDesign(np.array([0.0, 10.0, 5.0]), *(np.zeros(3),) * 3)


def test_lines_longer_than_any_run_are_refused_without_overflow() -> None:
    # a length of 1e300 m overflowed the design's integrals (numpy warnings, NaN lateral)
    with np.errstate(all="raise"):
        tangent = {"type": "tangent", "length_m": 1e300}
        with pytest.raises(DesignError, match=r"line\.toml: segment 2\.length_m: got 1e\+300"):
            design_from_segments([CURVE[0], tangent], source="line.toml")
        transition = {"type": "transition", "length_m": 1e300}
        with pytest.raises(DesignError, match=r"segment 2\.length_m: .*maximum 2e\+07 m"):
            design_from_segments([CURVE[0], transition, CURVE[2]])
        long = {"type": "tangent", "length_m": 1.5e7}
        with pytest.raises(DesignError, match=r"segment 2: the line reaches 3e\+07 m at its end"):
            design_from_segments([long, long])
        with pytest.raises(DesignError, match=r"run\.h5\.chainage_m: got 1e\+300 m at knot 1"):
            TrackDesign(np.array([0.0, 1e300]), *(np.zeros(2),) * 3, source="run.h5")
        assert design_from_segments([{"type": "tangent", "length_m": 2e7}]).end_m == 2e7


def test_a_design_that_does_not_cover_the_run_is_refused() -> None:
    design = design_from_segments(CURVE[:1])
    design.check_covers(0.0, 100.0)
    with pytest.raises(DesignError, match=r"covers 0 … 100 m but the run needs"):
        design.check_covers(0.0, 250.0)
    with pytest.raises(DesignError, match="outside the design record"):
        design.curvature(101.0)


def test_transitions_need_neighbours() -> None:
    with pytest.raises(DesignError, match="cannot be the first segment"):
        design_from_segments([{"type": "transition", "length_m": 10.0}, *CURVE[2:3]])
    with pytest.raises(DesignError, match="both transitions"):
        design_from_segments([CURVE[0], CURVE[1], CURVE[1], CURVE[2]])


def test_line_files_round_trip_and_name_the_file(tmp_path: Path) -> None:
    path = tmp_path / "line.toml"
    path.write_text(
        '[line]\nname = "demo"\n\n'
        '[[segments]]\ntype = "tangent"\nlength_m = 100.0\n\n'
        '[[segments]]\ntype = "transition"\nlength_m = 100.0\n\n'
        '[[segments]]\ntype = "curve"\nlength_m = 500.0\nradius_m = 2000.0\n'
        'cant_mm = 100.0\ndirection = "left"\ngradient_permille = 5.0\n'
    )
    design = load_line(path)
    reference = design_from_segments(CURVE[:3])
    np.testing.assert_array_equal(design.chainage_m, reference.chainage_m)
    np.testing.assert_array_equal(design.cant_m, reference.cant_m)
    bad = tmp_path / "bad.toml"
    bad.write_text(
        '[[segments]]\ntype = "curve"\nlength_m = 10\nradius_m = 90\ndirection = "left"\n'
    )
    with pytest.raises(DesignError, match=f"{bad}: segment 1.radius_m"):
        load_line(bad)
    with pytest.raises(DesignError, match="does not exist"):
        load_line(tmp_path / "missing.toml")
    segment = '[[segments]]\ntype = "tangent"\nlength_m = 100.0\n'
    for header, message in [
        ("[line]\nradius_m = 2000.0\n", r"\[line\]: unknown key\(s\) \['radius_m'\]"),
        ("line = 3\n", "expected a \\[line\\] table"),
        ("[line]\nname = 3\n", "expected a string"),
    ]:  # a segment key under [line] was silently ignored
        bad.write_text(header + "\n" + segment)
        with pytest.raises(DesignError, match=message):
            load_line(bad)
