"""The trend figure tells raised alarms from carried-over ones and says when none is possible."""

from __future__ import annotations

from typing import Any

import matplotlib.pyplot as plt
import pytest

from susp_bo.monitoring.figures import trend_plot


def _state(median: float, p_outside: float | None, alarm: bool) -> dict[str, Any]:
    return {"median": median, "interval95": [median - 1e3, median + 1e3], "p_outside": p_outside,
            "alarm": alarm, "truth": None}  # fmt: skip


def _payload(acceptable: list[float] | None) -> dict[str, Any]:
    rows = [  # trusted in the domain, trusted in alarm, not trusted (alarm carried over)
        ("2026-01-10", True, _state(40e3, 0.0, False)),
        ("2026-02-10", True, _state(25e3, 0.987, True)),
        ("2026-03-10", False, _state(16e3, 1.0, True)),
    ]
    return {
        "parameters": ["damping"], "units": ["N·s/m"], "bounds": [[15e3, 80e3]],
        "nominal": [40e3], "acceptable": [acceptable], "vehicles": ["A"], "alarm_threshold": 0.9,
        "campaigns": [
            {"vehicle": "A", "date": d, "trusted": t, "parameters": {"damping": s}}
            for d, t, s in rows
        ],
    }  # fmt: skip


@pytest.mark.parametrize("acceptable", [[30e3, 56e3], None])
def test_the_legend_tells_what_each_mark_means(acceptable: list[float] | None) -> None:
    fig = trend_plot(_payload(acceptable), "damping")
    try:
        ax = fig.axes[0]
        labels = {t.get_text() for t in ax.get_legend().get_texts()}
        assert {"alarm, P(outside)", "alarm carried over (campaign not trusted)",
                "not trusted: not used for alarms"} <= labels  # fmt: skip
        assert ("acceptable domain" in labels) == (acceptable is not None)
        assert ("no acceptable domain: no alarm possible" in labels) == (acceptable is None)
        # the trusted alarm carries its probability; the carried-over one does not
        assert [t.get_text() for t in ax.texts] == ["P = 0.987"]
        assert "P(outside) > 0.9" in ax.get_title()
        assert ax.get_ylabel() == "damping [kN·s/m]"
    finally:
        plt.close(fig)
