"""Which single-component failures the sensors can localise: spectral signatures and angles.

A *failure* sets one component's parameter (a per-component name such as
``yaw_damper_damping@bogie_front_left``, see :mod:`susp_bo.rig.components`) to a
fraction of its nominal value, e.g. a yaw damper at 50 % damping. Its *signature* is
the change of every channel's log-amplitude spectrum, in dB (``20 log10`` of the
amplitude ratio), against the nominal car on the same track: a (C x F) array.

Two failures can be told apart when their signatures point in different directions.
With the size of each failure unknown (what a calibration of both parameters
estimates), the angle θ between the two signatures — flattened over the chosen
channels and bands, in dB — is what matters: in a least-squares (Gauss–Newton) fit of
both parameters to log spectra, their posterior correlation is ``−cos θ`` and each
posterior sd is ``1/sin θ`` times what it would be with the other one known. Verdicts
(:data:`NOT_LOCALISABLE_COS`, :data:`LOCALISABLE_COS`): ``|cos θ| >= 0.98`` (θ <= 11.5°,
sd x 5 or more): not localisable — the data say "one of the two", a wide, correlated
posterior is the honest answer; ``|cos θ| <= 0.8`` (θ >= 37°, sd x 1.7 or less):
localisable; in between: weak. Signatures are secants (the failure's full change), not
derivatives, and say nothing about noise: a signature far below the spectral scatter of
a record (about 1 dB per band for 30 s records) is invisible whatever its direction.
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
NOT_LOCALISABLE_COS = 0.98
"""|cos θ| at or above which two failures are not localisable (θ <= 11.5°)."""
LOCALISABLE_COS = 0.8
"""|cos θ| at or below which two failures are localisable (θ >= 36.9°)."""
DEFAULT_TYPES = ("yaw_damper_damping", "secondary_vertical_damping", "primary_vertical_damping")


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
            raise ValueError(
                f"parameters: got {parameter!r}; it has no per-component form; parameters "
                f"with one: {', '.join(forms)}"
            )
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
            raise ValueError(
                f"channels: got {channels!r}; no channel starts with it (channels: "
                f"{', '.join(self.channels)})"
            )
        return mask

    def rms_db(self) -> FloatArray:
        """RMS change over the band of each failure and channel, (K x C) dB."""
        return np.sqrt(np.mean(self.change_db**2, axis=2))

    def cosine(self, first: str, second: str, channels: str = "all") -> float:
        """cos θ between two failures' signatures over the chosen channels (all bands)."""
        mask = self.channel_mask(channels)
        a = self.change_db[self.index(first)][mask].ravel()
        b = self.change_db[self.index(second)][mask].ravel()
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
        cosine: cos θ of the two signatures (= −posterior correlation of a joint fit).
        angle_deg: θ in degrees, in [0, 180].
        sd_inflation: 1/sin θ, the posterior-sd factor against the other one known.
        distinct_db: rms (over the chosen channels and bands) of the part of the smaller
            signature that no scaling of the other explains, ``min(|a|, |b|) sin θ / √N``
            dB: compare with the spectral scatter of a record (~1 dB per band).
        verdict: ``localisable``, ``weak`` or ``not localisable``.
    """

    first: str
    second: str
    channels: str
    cosine: float
    angle_deg: float
    sd_inflation: float
    distinct_db: float
    verdict: str


def verdict(cosine: float) -> str:
    """``localisable`` / ``weak`` / ``not localisable`` from |cos θ| (see the module doc)."""
    if not np.isfinite(cosine) or abs(cosine) >= NOT_LOCALISABLE_COS:
        return "not localisable"
    return "localisable" if abs(cosine) <= LOCALISABLE_COS else "weak"


def pair_separation(
    signatures: FailureSignatures, first: str, second: str, channels: str = "all"
) -> PairSeparation:
    """The angle between two failures' signatures and the verdict."""
    cosine = signatures.cosine(first, second, channels)
    sine = float(np.sqrt(max(0.0, 1.0 - cosine**2))) if np.isfinite(cosine) else 0.0
    mask = signatures.channel_mask(channels)
    smaller = min(
        float(np.sqrt(np.mean(signatures.change_db[signatures.index(name)][mask] ** 2)))
        for name in (first, second)
    )
    return PairSeparation(
        first,
        second,
        channels,
        cosine,
        float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))),
        1.0 / sine if sine > 0.0 else float("inf"),
        smaller * sine,
        verdict(cosine),
    )


def _short(channel: str) -> str:
    """``carbody_front_vertical`` -> ``cb_f_v``; ``bogie_rear_lateral`` -> ``bg_r_l``."""
    words = channel.split("_")
    head = {"carbody": "cb", "bogie": "bg"}.get(words[0], words[0][:2])
    return "_".join([head, *(w[0] for w in words[1:])])


def format_signatures(signatures: FailureSignatures) -> str:
    """Per failure: rms change (dB) in every channel, as fixed-width text."""
    width = max(len(f.label) for f in signatures.failures)
    head = " ".join(f"{_short(c):>7s}" for c in signatures.channels)
    lines = [f"{'failure':{width}s} {head}"]
    for failure, rms in zip(signatures.failures, signatures.rms_db()):
        lines.append(f"{failure.label:{width}s} " + " ".join(f"{v:7.3f}" for v in rms))
    legend = ", ".join(f"{_short(c)} = {c}" for c in signatures.channels)
    return "\n".join([*lines, f"(rms dB over the band; {legend})"])


def format_separations(rows: Sequence[PairSeparation]) -> str:
    """The pair table as fixed-width text."""
    width = max(len(r.first) for r in rows)
    second = max(len(r.second) for r in rows)
    lines = [
        f"{'first':{width}s} {'second':{second}s} {'channels':12s} {'cos':>6s} "
        f"{'angle°':>7s} {'sd x':>6s} {'dist dB':>7s} verdict"
    ]
    for r in rows:
        lines.append(
            f"{r.first:{width}s} {r.second:{second}s} {r.channels:12s} {r.cosine:6.3f} "
            f"{r.angle_deg:7.2f} {r.sd_inflation:6.2f} {r.distinct_db:7.3f} {r.verdict}"
        )
    return "\n".join(lines)
