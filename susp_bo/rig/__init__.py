"""The vehicle rig: rig specs, track irregularities, the PyBullet world, sensors, spectra.

Public API (imported lazily so that ``import susp_bo.rig`` does not start PyBullet):

* :func:`load_rig_spec`, :class:`RigSpec`, :class:`CalibrationParameter` — rigs as data.
* :class:`Rig`, :class:`RigResponse`, :class:`SimulationFailed`, :func:`synthetic_track`
  — the time-domain simulator ``h_sim(x, w)`` on PyBullet.
* :class:`LinearisedRig` — the frequency-domain model of the same spec.
* :class:`TrackDesign`, :func:`load_line` — the line's design (curves, cant, gradient).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "CalibrationParameter": "susp_bo.rig.spec",
    "RigSpec": "susp_bo.rig.spec",
    "load_rig_spec": "susp_bo.rig.spec",
    "Rig": "susp_bo.rig.simulator",
    "synthetic_track": "susp_bo.rig.simulator",
    "RigResponse": "susp_bo.rig.response",
    "SimulationFailed": "susp_bo.rig.response",
    "LinearisedRig": "susp_bo.rig.linear",
    "TrackDesign": "susp_bo.rig.design",
    "load_line": "susp_bo.rig.line_file",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name in _EXPORTS:
        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'susp_bo.rig' has no attribute {name!r}")
