"""One-at-a-time sensitivity of the spectra to the calibration parameters.

For each calibration parameter, the rig is run at the lower and upper bound of
its admissible interval (others at reference) on the same track, and the
change of every channel's log-amplitude spectrum is measured in dB
(``20 log10`` of the amplitude ratio). Used by the tests, the benchmark and the
rig-tour notebook to show that each parameter is visible in some channel.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import Spectra

FloatArray = NDArray[np.float64]
DB_PER_NEPER = 20.0 / np.log(10.0)


@dataclass(frozen=True)
class SensitivityRow:
    """Largest spectral change caused by one parameter at one end of its interval.

    Attributes:
        parameter: calibration parameter name.
        bound: ``lower`` or ``upper``.
        value: the parameter value used.
        channel: channel with the largest RMS change over the band.
        rms_db: that RMS change (dB).
        max_db: largest absolute change in that channel (dB).
        frequency_hz: where the largest change occurs (Hz).
    """

    parameter: str
    bound: str
    value: float
    channel: str
    rms_db: float
    max_db: float
    frequency_hz: float


def sensitivity_table(
    spec: RigSpec,
    spectra_of: Callable[[dict[str, float]], Spectra],
) -> list[SensitivityRow]:
    """Spectral change per parameter and bound.

    Args:
        spec: the rig (calibration set and bounds).
        spectra_of: ``parameters -> Spectra`` (e.g. a Rig run on a fixed track, or
            the linearised model); called with ``{}`` for the reference.
    """
    reference = spectra_of({})
    rows = []
    for entry in spec.calibration:
        for bound, value in (("lower", entry.lower), ("upper", entry.upper)):
            change = DB_PER_NEPER * (
                spectra_of({entry.name: value}).log_amplitude - reference.log_amplitude
            )
            rms = np.sqrt(np.mean(change**2, axis=1))
            c = int(np.argmax(rms))
            f = int(np.argmax(np.abs(change[c])))
            rows.append(
                SensitivityRow(
                    entry.name,
                    bound,
                    value,
                    reference.channels[c],
                    float(rms[c]),
                    float(np.abs(change[c, f])),
                    float(reference.frequencies_hz[f]),
                )
            )
    return rows


def format_sensitivity(rows: list[SensitivityRow]) -> str:
    """The table as fixed-width text."""
    lines = [
        f"{'parameter':32s} {'bound':6s} {'value':>10s} {'most affected channel':24s} "
        f"{'rms dB':>7s} {'max dB':>7s} {'at Hz':>6s}"
    ]
    for r in rows:
        lines.append(
            f"{r.parameter:32s} {r.bound:6s} {r.value:10.4g} {r.channel:24s} "
            f"{r.rms_db:7.2f} {r.max_db:7.2f} {r.frequency_hz:6.2f}"
        )
    return "\n".join(lines)
