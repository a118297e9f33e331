"""Each of the seven calibration parameters visibly changes some channel's spectrum."""

from __future__ import annotations

from susp_bo.rig.sensitivity import format_sensitivity, sensitivity_table
from susp_bo.rig.simulator import Rig
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.track import TrackGeometry

VISIBLE_DB = 1.0  # a change a maintainer can see on a spectrum plot


def test_every_calibration_parameter_is_visible_in_the_pybullet_spectra(
    short_spec: RigSpec, short_track: TrackGeometry
) -> None:
    with Rig(short_spec) as rig:
        rows = sensitivity_table(short_spec, lambda p: rig.spectra(short_track, parameters=p))
    print("\n" + format_sensitivity(rows))
    for name in short_spec.calibration_names:
        strongest = max((r for r in rows if r.parameter == name), key=lambda r: r.rms_db)
        assert strongest.rms_db > VISIBLE_DB, strongest
        assert strongest.max_db > 2 * VISIBLE_DB, strongest
