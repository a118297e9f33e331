"""Out-of-library changes: physics the effects library does not represent (test sets).

The discrepancy workflow must flag these and must *not* name a library effect
for them (``verdict: "unexplained_disagreement"``). They are made without the
effects library, by changing the generating rig's data or the measured
accelerations directly:

==========================  ===========================================================
kind                        what changes (generator only; the model keeps the base rig)
==========================  ===========================================================
``high_conicity``           worn wheel/rail profiles: equivalent conicity 0.10 → 0.35
                            (wheelset kinematic frequency and bogie lateral response up;
                            conicity is not in C_w and no library effect changes it)
``primary_lateral_soft``    primary lateral (axlebox) stiffness halved, 6.47 → 3.2 MN/m
                            (worn guidance bushes: an element not in C_w)
``sensor_on_bracket``       the carbody front lateral accelerometer on a compliant bracket
                            (a 6 Hz, 10 % damped base-excited oscillator between car and
                            sensor)
``sensor_rolled``           the front bogie lateral accelerometer mounted rolled by 20°:
                            it reads cos θ · lateral + sin θ · vertical
``sensor_misplaced``        the carbody front accelerometers mounted at x = 4.0 m instead
                            of above the bogie (8.75 m): less pitch in the vertical channel
==========================  ===========================================================

Each :class:`Modification` acts on a :class:`~susp_bo.rig.spec.RigSpec` (fast path),
on a rig TOML document (the command-line path: ``susp-bo synth`` on a modified rig
file) and on measured signals (C x n_t) or a :class:`~susp_bo.data.measured.MeasuredRun`.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from susp_bo.rig.spec import RigSpec

FloatArray = np.ndarray


@dataclass(frozen=True)
class Modification:
    """A change of the true vehicle (or its instrumentation) outside the effects library.

    Attributes:
        name: short name.
        physics: one line for engineers.
        parameters: named rig parameters set in the generator, ``{name: value}`` (SI).
        sensor_positions: ``{sensor name: (x, y, z) m}`` moved in the generator.
        mixing: ``(target, source, angle_deg)``: channel ``target`` reads
            ``cos θ · target + sin θ · source`` (an accelerometer rolled by θ).
        bracket: ``(channel, frequency_hz, damping_ratio)``: the accelerometer of
            ``channel`` sits on a compliant bracket, a base-excited oscillator with
            transmissibility ``(1 + 2iζr) / (1 − r² + 2iζr)``, ``r = f / f_n``.
    """

    name: str
    physics: str
    parameters: Mapping[str, float] = field(default_factory=dict)
    sensor_positions: Mapping[str, tuple[float, float, float]] = field(default_factory=dict)
    mixing: tuple[str, str, float] | None = None
    bracket: tuple[str, float, float] | None = None

    def apply_spec(self, spec: RigSpec) -> RigSpec:
        """The generating rig: parameters changed and sensors moved (no signal mixing)."""
        spec = spec.with_parameters(dict(self.parameters))
        if self.sensor_positions:
            known = set(spec.channels)
            unknown = sorted(set(self.sensor_positions) - known)
            if unknown:
                raise ValueError(f"{self.name}: unknown sensors {unknown}; rig has {sorted(known)}")
            sensors = tuple(
                dataclasses.replace(s, position_m=tuple(self.sensor_positions[s.name]))
                if s.name in self.sensor_positions
                else s
                for s in spec.sensors
            )
            spec = dataclasses.replace(spec, sensors=sensors)
        return spec

    def apply_document(self, document: Mapping[str, Any]) -> dict[str, Any]:
        """A rig TOML document (as parsed by ``tomllib``) changed the same way."""
        out = copy.deepcopy(dict(document))
        for name, value in self.parameters.items():
            section, key = _split_parameter(out, name)
            out[section][key] = float(value)
        for sensor in out.get("sensors", []):
            if sensor.get("name") in self.sensor_positions:
                sensor["position_m"] = [float(v) for v in self.sensor_positions[sensor["name"]]]
        return out

    @property
    def changes_signals(self) -> bool:
        """True when the measured accelerations themselves are changed."""
        return self.mixing is not None or self.bracket is not None

    def apply_signals(
        self, signals: FloatArray, channels: tuple[str, ...], sample_rate_hz: float
    ) -> FloatArray:
        """Measured accelerations (C x n_t, sampled at ``sample_rate_hz``) as the
        mis-mounted sensor reads them (a copy)."""
        out = np.array(signals, dtype=np.float64, copy=True)
        if self.mixing is not None:
            target, source, angle = self.mixing
            i, j = channels.index(target), channels.index(source)
            theta = math.radians(angle)
            out[i] = math.cos(theta) * signals[i] + math.sin(theta) * signals[j]
        if self.bracket is not None:
            channel, frequency, damping = self.bracket
            i = channels.index(channel)
            out[i] = bracket_response(out[i], sample_rate_hz, frequency, damping)
        return out

    def apply_run(self, run: Any) -> Any:
        """A :class:`~susp_bo.data.measured.MeasuredRun` with :meth:`apply_signals` applied."""
        if not self.changes_signals:
            return run
        signals = self.apply_signals(
            run.accelerations_m_s2, tuple(run.channels), run.sample_rate_hz
        )
        metadata = {**run.metadata, "out_of_library": self.name}
        return dataclasses.replace(run, accelerations_m_s2=signals, metadata=metadata)


def bracket_response(
    signal: FloatArray, sample_rate_hz: float, frequency_hz: float, damping_ratio: float
) -> FloatArray:
    """Acceleration (n_t,) read on a bracket of natural frequency ``frequency_hz`` (Hz) and
    damping ratio ``damping_ratio``, excited at its base by ``signal`` (m/s²): the
    transmissibility ``(1 + 2iζr) / (1 − r² + 2iζr)`` applied by FFT (periodic)."""
    x = np.asarray(signal, dtype=np.float64)
    r = np.fft.rfftfreq(x.size, 1.0 / sample_rate_hz) / frequency_hz
    gain = (1 + 2j * damping_ratio * r) / (1 - r**2 + 2j * damping_ratio * r)
    return np.fft.irfft(np.fft.rfft(x) * gain, n=x.size)


def _split_parameter(document: Mapping[str, Any], name: str) -> tuple[str, str]:
    """``contact_equivalent_conicity`` -> (``contact``, ``equivalent_conicity``)."""
    for section, table in document.items():
        if isinstance(table, dict) and name.startswith(f"{section}_"):
            key = name[len(section) + 1 :]
            if key in table:
                return section, key
    raise ValueError(f"parameter {name!r}: no [section] key of the rig document matches")


MODIFICATIONS: dict[str, Modification] = {
    m.name: m
    for m in (
        Modification(
            "high_conicity",
            "worn wheel/rail profiles: equivalent conicity 0.10 -> 0.35",
            parameters={"contact_equivalent_conicity": 0.35},
        ),
        Modification(
            "primary_lateral_soft",
            "worn axlebox guidance bushes: primary lateral stiffness 6.47 -> 3.2 MN/m",
            parameters={"primary_lateral_stiffness": 3.2e6},
        ),
        Modification(
            "sensor_on_bracket",
            "front carbody lateral accelerometer on a compliant bracket (6 Hz, 10 % damping)",
            bracket=("carbody_front_lateral", 6.0, 0.1),
        ),
        Modification(
            "sensor_rolled",
            "front bogie lateral accelerometer mounted rolled by 20 deg (reads vertical too)",
            mixing=("bogie_front_lateral", "bogie_front_vertical", 20.0),
        ),
        Modification(
            "sensor_misplaced",
            "front carbody accelerometers at x = 4.0 m instead of 8.75 m (above the bogie)",
            sensor_positions={
                "carbody_front_vertical": (4.0, 0.0, 1.25),
                "carbody_front_lateral": (4.0, 0.0, 1.25),
            },
        ),
    )
}
"""The out-of-library test set, by name."""


def get_modification(name: str) -> Modification:
    """The modification ``name`` (ValueError naming the known ones otherwise)."""
    if name not in MODIFICATIONS:
        raise ValueError(f"modification: got {name!r}; known: {', '.join(MODIFICATIONS)}")
    return MODIFICATIONS[name]
