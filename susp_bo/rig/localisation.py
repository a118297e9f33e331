"""Which single-component failures the sensors can localise: spectral signatures and angles.

A *failure* sets one component's parameter (a per-component name such as
``yaw_damper_damping@bogie_front_left``, see :mod:`susp_bo.rig.components`) to a
fraction of its nominal value, e.g. a yaw damper at 50 % damping. Its *signature* is
the change of every channel's log-amplitude spectrum, in dB (``20 log10`` of the
amplitude ratio), against the nominal car on the same track: a (C x F) array.

Two failures can be told apart when their signatures differ by more than the scatter σ
of a measured spectrum (dB; one number or one per channel and band). With the size of
each failure unknown (what a calibration of both estimates), what counts is the part of
one signature that no scaling of the other mimics: with a, b the signatures divided by
σ and θ their angle, that part has norm ``z = min(|a|, |b|) sin θ``. In a least-squares
(Gauss–Newton) fit of both parameters to log spectra with independent scatter σ, their
posterior correlation is ``−cos θ``, each posterior sd is ``1/sin θ`` times what it is
with the other known, and z is by how many σ the data prefer the right component to the
best imitation by the other (log-likelihood ratio ``z²/2``). Verdicts: z >= 5
(:data:`LOCALISABLE_Z`) localisable; z < 2 (:data:`NOT_LOCALISABLE_Z`) not localisable —
the data say "one of the two", a wide, correlated posterior is the honest answer; weak
in between. σ is about 1.5 dB when the runs' tracks are unknown (the replicate scatter
σ_B of the ``unpaired`` model), far less with the ``paired`` model (track measured:
sensor noise only; ``benchmarks/component_localisation.py`` computes it per band). z
assumes independent bands (optimistic at low frequency, where neighbouring bands share
Welch bins) and secant signatures (the failure's full change, not a derivative).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.components import component_name, component_parameters
from susp_bo.rig.sensitivity import DB_PER_NEPER
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import Spectra

FloatArray = NDArray[np.float64]
Scatter = float | FloatArray
"""σ of one value of a measured log spectrum (dB): one number, or one per (C x F)."""
LOCALISABLE_Z = 5.0
"""z (σ) at or above which two failures are localisable."""
NOT_LOCALISABLE_Z = 2.0
"""z (σ) below which two failures are not localisable."""
UNKNOWN_TRACK_SCATTER_DB = 1.5
"""Scatter of one band of a measured log spectrum when the track is unknown (dB)."""
DEFAULT_TYPES = ("yaw_damper_damping", "secondary_vertical_damping", "primary_vertical_damping")


def _sigma(scatter_db: Scatter, shape: tuple[int, ...]) -> FloatArray:
    sigma = np.broadcast_to(np.asarray(scatter_db, dtype=np.float64), shape)
    if not np.all(sigma > 0.0):
        raise ValueError(f"scatter_db: got min {np.min(sigma)}; must be > 0 dB everywhere")
    return sigma


@dataclass(frozen=True)
class ComponentFailure:
    """One component's parameter set to a fraction of its nominal value.

    Attributes:
        parameter: the per-component name, e.g. ``yaw_damper_damping@bogie_front_left``.
        value: the failed value (the parameter's unit, e.g. N·s/m).
        fraction: value / nominal, e.g. 0.5.
    """

    parameter: str
    value: float
    fraction: float

    @property
    def label(self) -> str:
        """Short label: ``yaw_damper_damping@bogie_front_left 50%``."""
        return f"{self.parameter} {100 * self.fraction:.0f}%"


def single_component_failures(
    spec: RigSpec, parameters: Sequence[str] = DEFAULT_TYPES, fraction: float = 0.5
) -> tuple[ComponentFailure, ...]:
    """Every component of each type-level parameter at ``fraction`` of its nominal value.

    Args:
        spec: the rig (nominal values).
        parameters: type-level names with a per-component form.
        fraction: failed value / nominal, > 0.

    Raises:
        ValueError: a parameter without a per-component form, or fraction <= 0.
    """
    if not fraction > 0.0:
        raise ValueError(f"fraction: got {fraction}; must be > 0")
    forms = component_parameters(spec.topology)
    failures = []
    for parameter in parameters:
        if parameter not in forms:
            raise ValueError(f"parameters: got {parameter!r}; it has no per-component form")
        for component in forms[parameter]:
            name = component_name(parameter, component)
            nominal = spec.parameters.get(name, spec.parameters[parameter])
            failures.append(ComponentFailure(name, fraction * nominal, fraction))
    return tuple(failures)


@dataclass(frozen=True)
class FailureSignatures:
    """Spectral signatures of K failures.

    Attributes:
        failures: the failures (K,).
        channels: channel names (C,).
        frequencies_hz: band centres (F,) Hz.
        change_db: spectral change of each failure, (K x C x F) dB.
    """

    failures: tuple[ComponentFailure, ...]
    channels: tuple[str, ...]
    frequencies_hz: FloatArray
    change_db: FloatArray

    def index(self, parameter: str) -> int:
        """Position of the failure of ``parameter`` (a per-component name)."""
        for k, failure in enumerate(self.failures):
            if failure.parameter == parameter:
                return k
        names = ", ".join(f.parameter for f in self.failures)
        raise KeyError(f"no failure of {parameter!r}; failures: {names}")

    def channel_mask(self, channels: str = "all") -> NDArray[np.bool_]:
        """Channels whose name starts with ``channels`` (``all``: every one), (C,)."""
        mask = np.array([channels == "all" or c.startswith(channels) for c in self.channels])
        if not mask.any():
            names = ", ".join(self.channels)
            raise ValueError(f"channels: got {channels!r}; no channel starts with it ({names})")
        return mask

    def rms_db(self) -> FloatArray:
        """RMS change over the band of each failure and channel, (K x C) dB."""
        return np.sqrt(np.mean(self.change_db**2, axis=2))

    def whitened(self, scatter_db: Scatter, channels: str = "all") -> FloatArray:
        """Signatures / σ (dB / dB: a number or (C x F)) over the chosen channels, (K x C'F).

        Raises:
            ValueError: σ not > 0 everywhere, or of another shape than (C x F).
        """
        sigma = _sigma(scatter_db, self.change_db.shape[1:])
        mask = self.channel_mask(channels)
        return (self.change_db[:, mask] / sigma[mask]).reshape(len(self.failures), -1)

    def detection_z(self, scatter_db: Scatter, channels: str = "all") -> FloatArray:
        """By how many σ each failure stands out from the nominal car, ``|a/σ|``, (K,)."""
        return np.linalg.norm(self.whitened(scatter_db, channels), axis=1)

    def cosine(
        self, first: str, second: str, channels: str = "all", scatter_db: Scatter = 1.0
    ) -> float:
        """cos θ between two failures' signatures divided by σ, over the chosen channels."""
        values = self.whitened(scatter_db, channels)
        a, b = values[self.index(first)], values[self.index(second)]
        norm = float(np.linalg.norm(a) * np.linalg.norm(b))
        return float(a @ b) / norm if norm > 0.0 else float("nan")


def failure_signatures(
    spectra_of: Callable[[dict[str, float]], Spectra],
    failures: Sequence[ComponentFailure],
) -> FailureSignatures:
    """The signatures of ``failures`` (one spectra call each, plus the nominal).

    Args:
        spectra_of: ``parameters -> Spectra`` on a fixed track (e.g.
            ``LinearisedRig(spec).spectra``); called with ``{}`` for the nominal car.
        failures: the failures.
    """
    nominal = spectra_of({})
    change = np.stack(
        [
            DB_PER_NEPER
            * (spectra_of({f.parameter: f.value}).log_amplitude - nominal.log_amplitude)
            for f in failures
        ]
    )
    return FailureSignatures(tuple(failures), nominal.channels, nominal.frequencies_hz, change)


@dataclass(frozen=True)
class PairSeparation:
    """Whether two failures' signatures can be told apart on some channels.

    Attributes:
        first, second: the per-component names.
        channels: ``all`` or a channel-name prefix (``carbody``, ``bogie``, ``bogie_front``).
        cosine: cos θ of the two signatures divided by σ (= −posterior correlation of a
            joint fit).
        angle_deg: θ in degrees, in [0, 180].
        sd_inflation: 1/sin θ, the posterior-sd factor against the other one known.
        scatter_db: rms of σ over the chosen values (dB; σ itself may vary by value).
        z: ``min(|a/σ|, |b/σ|) sin θ``, by how many σ the data tell the two apart.
        verdict: ``localisable`` (z >= 5), ``weak`` or ``not localisable`` (z < 2).
    """

    first: str
    second: str
    channels: str
    cosine: float
    angle_deg: float
    sd_inflation: float
    scatter_db: float
    z: float
    verdict: str


def verdict(z: float) -> str:
    """``localisable`` / ``weak`` / ``not localisable`` from z (see the module doc)."""
    if not np.isfinite(z) or z < NOT_LOCALISABLE_Z:
        return "not localisable"
    return "localisable" if z >= LOCALISABLE_Z else "weak"


def pair_separation(
    signatures: FailureSignatures,
    first: str,
    second: str,
    channels: str = "all",
    scatter_db: Scatter = UNKNOWN_TRACK_SCATTER_DB,
) -> PairSeparation:
    """The angle between two failures' signatures, z at ``scatter_db`` and the verdict.

    Args:
        signatures: the failures' signatures; first, second: two of their names.
        channels: ``all`` or a channel-name prefix (``carbody``, ``bogie``).
        scatter_db: σ of one value of a measured spectrum (dB): a number, or (C x F).

    Raises:
        ValueError: σ not > 0, or no channel starts with ``channels``.
    """
    cosine = signatures.cosine(first, second, channels, scatter_db)
    sine = float(np.sqrt(max(0.0, 1.0 - cosine**2))) if np.isfinite(cosine) else 0.0
    detection = signatures.detection_z(scatter_db, channels)
    z = min(detection[signatures.index(first)], detection[signatures.index(second)]) * sine
    sigma = _sigma(scatter_db, signatures.change_db.shape[1:])[signatures.channel_mask(channels)]
    rms_sigma = float(np.sqrt(np.mean(sigma**2)))
    return PairSeparation(
        first,
        second,
        channels,
        cosine,
        float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))),
        1.0 / sine if sine > 0.0 else float("inf"),
        rms_sigma,
        float(z),
        verdict(float(z)),
    )


def _short(channel: str) -> str:
    """``carbody_front_vertical`` -> ``cb_f_v``; ``bogie_rear_lateral`` -> ``bg_r_l``."""
    words = channel.split("_")
    head = {"carbody": "cb", "bogie": "bg"}.get(words[0], words[0][:2])
    return "_".join([head, *(w[0] for w in words[1:])])


def format_signatures(
    signatures: FailureSignatures, scatter_db: Scatter = UNKNOWN_TRACK_SCATTER_DB
) -> str:
    """Per failure: rms change (dB) in every channel and detection z at ``scatter_db``."""
    width = max(len(f.label) for f in signatures.failures)
    head = " ".join(f"{_short(c):>7s}" for c in signatures.channels)
    lines = [f"{'failure':{width}s} {head} {'z':>6s}"]
    detection = signatures.detection_z(scatter_db)
    for failure, rms, z in zip(signatures.failures, signatures.rms_db(), detection):
        values = " ".join(f"{v:7.3f}" for v in rms)
        lines.append(f"{failure.label:{width}s} {values} {z:6.1f}")
    legend = ", ".join(f"{_short(c)} = {c}" for c in signatures.channels)
    return "\n".join([*lines, f"(rms dB over the band; z = |change / σ|; {legend})"])


def format_separations(rows: Sequence[PairSeparation]) -> str:
    """The pair table as fixed-width text."""
    width = max(len(r.first) for r in rows)
    second = max(len(r.second) for r in rows)
    lines = [
        f"{'first':{width}s} {'second':{second}s} {'channels':12s} {'cos':>6s} "
        f"{'angle°':>7s} {'sd x':>6s} {'σ dB':>5s} {'z':>6s} verdict"
    ]
    for r in rows:
        lines.append(
            f"{r.first:{width}s} {r.second:{second}s} {r.channels:12s} {r.cosine:6.3f} "
            f"{r.angle_deg:7.2f} {min(r.sd_inflation, 999.0):6.2f} {r.scatter_db:5.2f} {r.z:6.1f} "
            f"{r.verdict}"
        )
    return "\n".join(lines)
