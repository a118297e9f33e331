"""The vehicle rig: rig specs, track irregularities, the PyBullet world, sensors, spectra."""

from __future__ import annotations
