"""SI-prefixed physical values: exact strings for the units the rigs use."""

from __future__ import annotations

import pytest

from susp_bo.units import format_quantity, format_range, format_values, unit_scale


@pytest.mark.parametrize(
    ("value", "unit", "text"),
    [
        (28000.0, "N·s/m", "28.0 kN·s/m"),
        (4.9e6, "N·s/m", "4.90 MN·s/m"),
        (1.176e6, "N/m", "1.18 MN/m"),
        (0.19e6, "N/m", "190 kN/m"),
        (2.5e6, "N·m/rad", "2.50 MN·m/rad"),
        (13.0e3, "N·s/m", "13.0 kN·s/m"),
        (999.7, "N/m", "1.00 kN/m"),  # rounding carries into the next prefix
        (850.0, "N/m", "850 N/m"),
        (0.005, "m/s²", "5.00 mm/s²"),
        (0.0021, "rad", "2.10 mrad"),
        (300.0 / 3.6, "m/s", "83.3 m/s"),
        (1.7, "m", "1.70 m"),
        (-3200.0, "N", "-3.20 kN"),
        (1500.0, "kg", "1.50 t"),
        (42.0, "kg", "42.0 kg"),
        (0.5, "", "0.500"),
        (2.0e4, "kg·m²", "20000 kg·m²"),  # takes no prefix: plain value
        (3.0e7, "kg·m²", "3.00e+07 kg·m²"),
        (0.0, "N/m", "0.00 N/m"),
    ],
)
def test_format_quantity(value: float, unit: str, text: str) -> None:
    assert format_quantity(value, unit) == text


def test_unit_scale_picks_the_prefix_of_the_magnitude() -> None:
    assert unit_scale(8.0e6, "N·s/m") == (1e6, "MN·s/m")
    assert unit_scale(80.0e3, "N·s/m") == (1e3, "kN·s/m")
    assert unit_scale(0.3e6, "N/m") == (1e3, "kN/m")
    assert unit_scale(5.0, "N/m") == (1.0, "N/m")
    assert unit_scale(0.0, "N/m") == (1.0, "N/m")
    assert unit_scale(5.0e6, "") == (1.0, "")
    assert unit_scale(5.0e6, "%") == (1.0, "%")


def test_ranges_and_groups_share_one_unit() -> None:
    assert format_range(0.5e6, 8.0e6, "N·s/m") == "0.50–8.00 MN·s/m"
    assert format_range(15.0e3, 80.0e3, "N·s/m") == "15.0–80.0 kN·s/m"
    assert format_range(0.12e6, 0.30e6, "N/m") == "120–300 kN/m"
    # a MAP and a narrow interval: enough decimals that the ends differ
    assert format_values([27.9e3, 27.85e3, 27.95e3], "N·s/m") == (
        ["27.90", "27.85", "27.95"],
        "kN·s/m",
    )
    # a reference written in the MAP's unit and precision
    assert format_values([3.7e6], "N·s/m", like=[4.39e6, 4.06e6, 4.72e6]) == (
        ["3.70"],
        "MN·s/m",
    )
    assert format_values([0.9e6], "N/m", like=[0.9e6, 0.5e6, 1.3e6]) == (["0.90"], "MN/m")
