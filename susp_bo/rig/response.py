"""The result of a rig run: sensor accelerations against time, and the failure type."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.spectra import Spectra, SpectrumSettings, log_amplitude_spectra

FloatArray = NDArray[np.float64]


class SimulationFailed(RuntimeError):
    """A simulation that diverged or could not run; never returned as spectra.

    Attributes:
        reason: short explanation (which quantity, which body, at what time).
    """

    def __init__(self, reason: str) -> None:
        super().__init__(f"simulation failed: {reason}")
        self.reason = reason


@dataclass(frozen=True)
class RigResponse:
    """Accelerometer signals of one run.

    Args:
        time_s: sample times (n,) s (centres of the averaging intervals).
        channels: channel names (C,).
        accelerations_m_s2: specific force along each sensor axis minus the static
            gravity, (C x n) m/s².
        sample_rate_hz: sampling rate (Hz).
        settings: default spectrum settings (the rig's), used by :meth:`spectra`.
        quasi_static_m_s2: on a line with a track design, the design's quasi-static
            specific force at every sensor (C x n) m/s²
            (:func:`~susp_bo.rig.curving.reference_specific_force`), removed from the
            signals before the spectra; None on tangent track.
    """

    time_s: FloatArray
    channels: tuple[str, ...]
    accelerations_m_s2: FloatArray
    sample_rate_hz: float
    settings: SpectrumSettings | None = None
    quasi_static_m_s2: FloatArray | None = None

    def __post_init__(self) -> None:
        time = np.asarray(self.time_s, dtype=np.float64)
        data = np.asarray(self.accelerations_m_s2, dtype=np.float64)
        if data.shape != (len(self.channels), time.size):
            raise ValueError(
                f"RigResponse.accelerations_m_s2: shape {data.shape}; expected "
                f"({len(self.channels)}, {time.size})"
            )
        object.__setattr__(self, "time_s", time)
        object.__setattr__(self, "accelerations_m_s2", data)
        object.__setattr__(self, "channels", tuple(self.channels))
        if self.quasi_static_m_s2 is not None:
            removed = np.asarray(self.quasi_static_m_s2, dtype=np.float64)
            if removed.shape != data.shape:
                raise ValueError(
                    f"RigResponse.quasi_static_m_s2: shape {removed.shape}; expected {data.shape}"
                )
            object.__setattr__(self, "quasi_static_m_s2", removed)

    def channel(self, name: str) -> FloatArray:
        """Signal of one channel, (n,) m/s²."""
        if name not in self.channels:
            raise KeyError(f"RigResponse: no channel {name!r}; channels: {self.channels}")
        return self.accelerations_m_s2[self.channels.index(name)]

    def spectra(self, settings: SpectrumSettings | None = None) -> Spectra:
        """Log-amplitude spectra of every channel (settings default to the rig's).

        On a designed line the design's quasi-static specific force is subtracted
        first (what is left: the dynamic response, plus the vehicle's own
        quasi-static roll-out, which measured and simulated runs share).
        """
        signals = self.accelerations_m_s2
        if self.quasi_static_m_s2 is not None:
            signals = signals - self.quasi_static_m_s2
        return log_amplitude_spectra(
            signals,
            self.sample_rate_hz,
            self.channels,
            settings if settings is not None else self.settings,
        )
