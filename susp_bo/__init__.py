"""susp_bo: Bayesian calibration of high-speed train suspensions.

The state of a train's suspensions is inferred from on-track accelerometer
measurements: a PyBullet vehicle rig is the simulator ``h_sim(x, w)``, a
GPyTorch kriging surrogate models the log-likelihood of the measured spectra
(eq. 4 of Lebel et al.), BoTorch expected improvement refines it (EGO) and a
Pyro Metropolis–Hastings kernel draws the posterior of the parameters ``w``.

The public API is re-exported here; see README.md for a tour.
"""

from __future__ import annotations

__version__ = "0.1.0"

from susp_bo.rig.catalog import available_rigs, rig_path

__all__ = [
    "__version__",
    "available_rigs",
    "rig_path",
]
