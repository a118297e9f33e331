"""``study.write_figures`` draws the rig's acceptable bands and the result's verdict.

The study and the result are stand-ins with the attributes ``write_figures`` reads: the
rig spec's ``acceptable`` (helper i13) and ``CalibrationResult.reliability`` (helper i10rel)
are read with ``getattr``, so this test runs before and after those branches are merged.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

import matplotlib.image
import numpy as np

from susp_bo.calibration.posterior import summarize
from susp_bo.calibration.study import write_figures


@dataclass(frozen=True)
class _Verdict:
    """Shape of ``susp_bo.calibration.reliability.Reliability`` that figures use."""

    verdict: str
    sentence: str

    def to_dict(self) -> dict:
        return {
            "verdict": self.verdict,
            "reasons": [{"code": "poor_mixing"}],
            "sentence": self.sentence,
        }


def _study(acceptable: tuple[float, float] | None) -> SimpleNamespace:
    names = ("secondary_vertical_damping", "yaw_damper_damping")
    calibration = [
        SimpleNamespace(name=names[0], unit="N·s/m", acceptable=acceptable),
        SimpleNamespace(name=names[1], unit="N·s/m"),  # no acceptable key at all
    ]
    return SimpleNamespace(
        names=names,
        bounds=np.array([[15.0e3, 0.5e6], [80.0e3, 8.0e6]]),
        reference=np.array([28.0e3, 3.7e6]),
        units=("N·s/m", "N·s/m"),
        spec=SimpleNamespace(calibration=calibration),
    )


def _result(study: SimpleNamespace, rng: np.random.Generator, verdict: object) -> SimpleNamespace:
    draws = np.column_stack([rng.normal(28.0e3, 400.0, 2000), rng.normal(4.4e6, 0.5e6, 2000)])
    unit = (draws - study.bounds[0]) / (study.bounds[1] - study.bounds[0])
    summary = summarize(unit.reshape(2, 1000, 2), study.bounds, study.names)
    return SimpleNamespace(summary=summary, samples=draws, reliability=verdict)


def test_write_figures_draws_band_and_verdict(tmp_path: Path, rng: np.random.Generator) -> None:
    plain = _study(None)
    result = _result(plain, rng, None)
    a = write_figures(plain, result, tmp_path / "a")  # type: ignore[arg-type]
    banded = _study((26.0e3, 48.0e3))
    b = write_figures(banded, result, tmp_path / "b")  # type: ignore[arg-type]
    result.reliability = _Verdict("not_trusted", "Not trusted: the chains did not mix.")
    c = write_figures(banded, result, tmp_path / "c")  # type: ignore[arg-type]
    for first, second, third in zip(a, b, c):
        image = [matplotlib.image.imread(p) for p in (first, second, third)]
        assert not np.array_equal(image[0], image[1])  # the band is drawn
        assert not np.array_equal(image[1], image[2])  # the verdict is drawn
