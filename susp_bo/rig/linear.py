"""Linearised frequency-domain model of a rig: the cross-check and the fast path.

Built from the same :class:`~susp_bo.rig.assembly.Assembly` as the PyBullet
world: mass, damping and stiffness matrices are ``Σ Gᵀ diag(slope) G`` over the
element groups (bilinear dampers at their initial slope, dead bands at their
slope at zero), the linear wheel–rail contact at speed V, and the series
spring–damper strokes as first-order states. In state-space form
``ż = A z + B x + B_d ẋ`` with ``z = [q, q̇, s]``, the accelerance of every
sensor to a unit track input at each axle is solved per frequency; axle inputs
are the same profile delayed by ``x_a / V``.

* :meth:`LinearisedRig.spectra`: expected Welch log-amplitude spectra for
  random track with the German PSDs (vertical, cross-level and alignment taken
  as independent), PSD ``S_t(f) = S(Ω) 2π / V`` with ``Ω = 2π f / V``.
* :meth:`LinearisedRig.response`: time signals for a given track realization
  (FFT filtering of the axle inputs), for a like-for-like check against PyBullet.
* :meth:`LinearisedRig.modes`: complex modes named by their dominant body motion.

The matrices and the transfer functions are built in :mod:`susp_bo.rig.state_space`; the
modal solve and the naming of modes are :mod:`susp_bo.rig.linear_modal`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import scipy.fft
from numpy.typing import NDArray

from susp_bo.rig.assembly import INPUTS_PER_AXLE, build_assembly
from susp_bo.rig.design import TrackDesign
from susp_bo.rig.linear_curving import CurvedLineMethods
from susp_bo.rig.linear_modal import Mode as Mode  # re-exported: importable from here
from susp_bo.rig.linear_modal import _label, _modal_basis, _ModalBasis, _solve_outputs
from susp_bo.rig.response import RigResponse
from susp_bo.rig.spec import RigSpec
from susp_bo.rig.spectra import Spectra, SpectrumSettings
from susp_bo.rig.state_space import StateSpace, sensor_transfer, state_space
from susp_bo.rig.track import AxleExcitation, TrackGeometry, TrackPSD

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]
_PSD_COMPONENTS = ("vertical", "cross_level", "alignment")


def _hann_kernel(offsets_hz: FloatArray, segment_s: float) -> FloatArray:
    """|Ŵ(ν)|² of a Hann window of length T, each row normalised to unit area (1/Hz).

    Args:
        offsets_hz: frequency offsets on a regular grid, (..., K) Hz.
        segment_s: window length T (s).
    """
    x = offsets_hz * segment_s
    near_one = np.isclose(np.abs(x), 1.0)
    w = np.sinc(x) / np.where(near_one, 1.0, 1.0 - x * x)
    w = np.where(near_one, 0.5, w)
    kernel = w * w
    spacing = offsets_hz[..., 1] - offsets_hz[..., 0]
    return kernel / (np.sum(kernel, axis=-1) * spacing)[..., None]


class LinearisedRig(CurvedLineMethods):
    """Frequency-domain model of a rig spec (same elements as the PyBullet world).

    Args:
        spec: the rig spec.
    """

    def __init__(self, spec: RigSpec) -> None:
        self.spec = spec
        # Fourier transforms of recent tracks' axle inputs (the track object is kept and
        # compared by identity, so a reused id cannot return another track's inputs)
        self._input_cache: dict[
            tuple, tuple[object, tuple[ComplexArray, ComplexArray], tuple[int, int]]
        ] = {}
        # the last state space built and its modal basis: the ν runs of one parameter
        # point (one response each) share them, so they are built once, not ν times
        self._last_system: tuple[tuple, StateSpace] | None = None
        self._last_basis: tuple[StateSpace, _ModalBasis] | None = None

    def _system(
        self,
        parameters: Mapping[str, float] | None,
        speed_m_s: float,
        dead_band_slopes: FloatArray | None = None,
    ) -> StateSpace:
        spec = self.spec.with_parameters(parameters)
        slopes = None if dead_band_slopes is None else np.asarray(dead_band_slopes, np.float64)
        # exact key (float.hex tells -0.0 from 0.0): a hit returns what would be rebuilt
        key = (
            tuple((name, float(value).hex()) for name, value in spec.parameters.items()),
            float(speed_m_s).hex(),
            None if slopes is None else (slopes.shape, slopes.tobytes()),
        )
        last = self._last_system  # read once: another thread may replace it
        if last is not None and last[0] == key:
            return last[1]
        system = state_space(build_assembly(spec), speed_m_s, dead_band_slopes)
        self._last_system = (key, system)
        return system

    def _modal_basis(self, system: StateSpace) -> _ModalBasis:
        """The eigen-decomposition of ``system.a`` (:func:`_modal_basis`), kept for the
        last system."""
        last = self._last_basis  # read once: another thread may replace it
        if last is None or last[0] is not system:
            last = (system, _modal_basis(system))
            self._last_basis = last
        return last[1]

    def eigenvalues(
        self, parameters: Mapping[str, float] | None = None, speed_m_s: float | None = None
    ) -> ComplexArray:
        """Eigenvalues of the state matrix (1/s); stable when every real part is < 0."""
        speed = self.spec.simulation.speed_m_s if speed_m_s is None else speed_m_s
        return np.linalg.eigvals(self._system(parameters, speed).a)

    def modes(
        self, parameters: Mapping[str, float] | None = None, speed_m_s: float | None = None
    ) -> list[Mode]:
        """Oscillatory modes, sorted by frequency, named ``<body kind>_<motion>``.

        The name is the (body kind, coordinate) pair with the largest share of the
        mode's kinetic energy, e.g. ``carbody_bounce``, ``bogie_pitch``.
        """
        speed = self.spec.simulation.speed_m_s if speed_m_s is None else speed_m_s
        system = self._system(parameters, speed)
        basis = self._modal_basis(system)
        values, vectors = basis.values, basis.vectors
        n = system.n_dofs
        assembly = system.assembly
        labels = [_label(name) for name in assembly.dof_names]
        modes = []
        for value, vector in zip(values, vectors.T):
            if value.imag <= 1e-6:
                continue
            energy = assembly.mass_diagonal * np.abs(vector[n : 2 * n]) ** 2
            shares: dict[str, float] = {}
            for label, e in zip(labels, energy):
                shares[label] = shares.get(label, 0.0) + float(e)
            total = sum(shares.values())
            name = max(shares, key=shares.__getitem__)
            modes.append(
                Mode(
                    name,
                    float(abs(value)) / (2 * np.pi),
                    float(-value.real / abs(value)),
                    shares[name] / total,
                )
            )
        return sorted(modes, key=lambda m: m.frequency_hz)

    def modal_frequencies_hz(
        self,
        parameters: Mapping[str, float] | None = None,
    ) -> dict[str, float]:
        """Undamped natural frequencies (Hz) of the vehicle on rigid track, by mode name.

        Dampers are removed (the series yaw dampers with them), the wheelsets are
        held on the track centre line; the lowest frequency of each named kind is
        kept, e.g. ``carbody_bounce``, ``carbody_pitch``, ``carbody_lateral``
        (lower sway), ``carbody_roll`` (upper sway), ``bogie_bounce``, ``bogie_pitch``.
        This is the usual definition of the "uncoupled" modes quoted in the literature.
        """
        assembly = build_assembly(self.spec.with_parameters(parameters))
        n = assembly.n_dofs
        k = np.zeros((n, n))
        for elements in (assembly.springs, assembly.dead_bands):
            g, slope = elements.group.coordinates, elements.slope()
            k += g.T @ (slope[:, None] * g)
        free = [i for i, name in enumerate(assembly.dof_names) if not name.startswith("wheelset")]
        scale = 1.0 / np.sqrt(assembly.mass_diagonal[free])
        values, vectors = np.linalg.eigh(scale[:, None] * k[np.ix_(free, free)] * scale[None, :])
        labels = [_label(assembly.dof_names[i]) for i in free]
        result: dict[str, float] = {}
        for value, vector in sorted(zip(values, vectors.T), key=lambda pair: pair[0]):
            shares: dict[str, float] = {}
            for label, share in zip(labels, vector**2):
                shares[label] = shares.get(label, 0.0) + float(share)
            name = max(shares, key=shares.__getitem__)
            result.setdefault(name, float(np.sqrt(max(value, 0.0))) / (2 * np.pi))
        return result

    def psd(
        self,
        frequencies_hz: FloatArray,
        parameters: Mapping[str, float] | None = None,
        psd: TrackPSD | None = None,
        speed_m_s: float | None = None,
        components: tuple[str, ...] = INPUTS_PER_AXLE,
        design: TrackDesign | None = None,
    ) -> FloatArray:
        """One-sided acceleration PSD of every sensor, (F x C) (m/s²)²/Hz, on random track.

        Args:
            frequencies_hz: where to evaluate (F,) Hz, > 0.
            parameters: named parameter values (default: the rig's).
            psd: track spectra (default: the rig's track quality).
            speed_m_s: constant speed (default: the rig's).
            components: track inputs to include (``vertical``, ``cross_level``, ``alignment``).
            design: a line with curves: the PSD is the time-weighted mean over the
                operating points of the recorded stretch (:meth:`operating_points`);
                None is tangent track.

        Raises:
            LinearModelNotApplicable: the design puts a dead band into contact.
        """
        if design is not None:
            points = self.operating_points(design, parameters, speed_m_s)
            return sum(
                point.weight
                * self._psd(
                    frequencies_hz, parameters, psd, speed_m_s, components, point.dead_band_slopes
                )
                for point in points
            )
        return self._psd(frequencies_hz, parameters, psd, speed_m_s, components)

    def _psd(
        self,
        frequencies_hz: FloatArray,
        parameters: Mapping[str, float] | None,
        psd: TrackPSD | None,
        speed_m_s: float | None,
        components: tuple[str, ...],
        dead_band_slopes: FloatArray | None = None,
    ) -> FloatArray:
        speed = self.spec.simulation.speed_m_s if speed_m_s is None else float(speed_m_s)
        psd = TrackPSD(self.spec.simulation.track_quality) if psd is None else psd
        fine = np.asarray(frequencies_hz, dtype=np.float64)
        system = self._system(parameters, speed, dead_band_slopes)
        transfer = sensor_transfer(system, fine, self.spec.simulation.sample_rate_hz)
        axles = system.assembly.axle_positions_m
        omega = 2.0 * np.pi * fine
        delays = np.exp(1j * omega[:, None] * axles[None, :] / speed)  # (F x n_axles)
        wavenumber = omega / speed
        psd_time = {
            "vertical": psd.vertical(wavenumber),
            "cross_level": psd.cross_level(wavenumber),
            "alignment": psd.alignment(wavenumber),
        }
        power = np.zeros((fine.size, transfer.shape[1]))
        for c, component in enumerate(INPUTS_PER_AXLE):
            if component not in components:
                continue
            columns = transfer[:, :, c :: len(INPUTS_PER_AXLE)]  # (F x C x n_axles)
            combined = np.einsum("fca,fa->fc", columns, delays)
            power += np.abs(combined) ** 2 * (psd_time[component] * 2 * np.pi / speed)[:, None]
        return power

    def spectra(
        self,
        parameters: Mapping[str, float] | None = None,
        psd: TrackPSD | None = None,
        speed_m_s: float | None = None,
        settings: SpectrumSettings | None = None,
        design: TrackDesign | None = None,
    ) -> Spectra:
        """Expected Welch log-amplitude spectra on random track (the fast path).

        Args:
            parameters: named parameter values (default: the rig's).
            psd: track spectra (default: the rig's track quality).
            speed_m_s: constant speed (default: the rig's).
            settings: spectrum settings (default: the rig's).
            design: a line with curves: the random part linearised about the
                operating points along it (see :meth:`psd`) plus the Welch PSD of the
                deterministic response to the design (:meth:`design_welch`: roll-out,
                transients at the transitions) — the design's reference specific force
                is removed, as from measured and PyBullet signals.

        Returns:
            Spectra (C x F) in ln((m/s²)/√Hz): the PSD convolved with the Hann
            window's kernel (what Welch estimates), band-averaged like spectra.py.

        Raises:
            TypeError: ``psd`` not a :class:`TrackPSD`, ``settings`` not a
                :class:`SpectrumSettings`.
            ValueError: the band reaches the Nyquist frequency of the rig's sample rate
                (the check :meth:`MeasuredRun.spectra` makes).
        """
        if psd is not None and not isinstance(psd, TrackPSD):
            raise TypeError(
                f"psd: {psd!r} ({type(psd).__name__}) is not allowed; expected a TrackPSD, "
                "e.g. TrackPSD('high'), or None for the rig's track quality"
            )
        if settings is not None and not isinstance(settings, SpectrumSettings):
            raise TypeError(
                f"settings: {settings!r} ({type(settings).__name__}) is not allowed; expected "
                "a SpectrumSettings or None for the rig's"
            )
        given = settings is not None
        settings = self.spec.spectrum if settings is None else settings
        try:  # an expected spectrum has no record length: one segment passes that part
            settings.check_sample_rate(self.spec.simulation.sample_rate_hz, settings.segment_s)
        except ValueError as error:
            where = "settings" if given else f"rig {self.spec.name!r}: [spectrum]"
            raise ValueError(
                f"{where}: {error} (against the rig's [simulation] sample_rate_hz)"
            ) from error
        resolution = 1.0 / settings.segment_s
        step = resolution / 8.0
        fine = np.arange(1, int(np.ceil((settings.f_max_hz + 6 * resolution) / step)) + 1) * step
        power = self.psd(fine, parameters, psd, speed_m_s, design=design)
        # expected Welch estimate at the Welch bins, then the band average of spectra.py
        bins = np.arange(0.0, settings.f_max_hz + 2 * resolution, resolution)
        both = np.concatenate([-fine[::-1], fine])
        full = np.concatenate([power[::-1], power])
        kernel = _hann_kernel(both[None, :] - bins[:, None], settings.segment_s)
        welch = (kernel @ full) * step
        speed = self.spec.simulation.speed_m_s if speed_m_s is None else float(speed_m_s)
        for line_hz, line_power in self.periodic_lines(parameters, speed):
            for centre in (line_hz, -line_hz):
                offset = (bins - centre) * settings.segment_s
                near_one = np.isclose(np.abs(offset), 1.0)
                shape = np.sinc(offset) / np.where(near_one, 1.0, 1 - offset**2)
                shape = np.where(near_one, 0.5, shape)
                welch += (settings.segment_s * shape**2 / 1.5)[:, None] * line_power[None, :]
        if design is not None:
            welch += self.design_welch(design, parameters, speed, settings)[: bins.size]
        welch[bins == 0] = 0.0
        band = _band_average(welch.T, resolution, settings.band_edges_hz())
        return Spectra(settings.frequencies_hz(), self.spec.channels, 0.5 * np.log(band))

    def periodic_lines(
        self, parameters: Mapping[str, float] | None, speed_m_s: float
    ) -> list[tuple[float, FloatArray]]:
        """Spectral lines of the deterministic inputs (wheel out-of-roundness) at constant speed.

        Returns:
            ``(frequency Hz, one-sided power per sensor (C,) (m/s²)²)`` per distinct
            wavenumber: the sinusoids of every axle at that wavenumber combined coherently.
        """
        system = self._system(parameters, speed_m_s)
        periodic = system.assembly.periodic_inputs
        lines: list[tuple[float, FloatArray]] = []
        for k in np.unique(periodic.wavenumber_rad_m):
            pick = periodic.wavenumber_rad_m == k
            f0 = float(k * speed_m_s / (2 * np.pi))
            transfer = sensor_transfer(system, np.array([f0]), self.spec.simulation.sample_rate_hz)
            amplitude = np.zeros(transfer.shape[2], dtype=complex)
            np.add.at(
                amplitude,
                periodic.input_index[pick],
                periodic.amplitude[pick] * np.exp(1j * periodic.phase_rad[pick]),
            )
            response = transfer[0] @ amplitude  # (C,)
            lines.append((f0, 0.5 * np.abs(response) ** 2))
        return lines

    def response(
        self,
        geometry: TrackGeometry,
        speed_m_s: float,
        parameters: Mapping[str, float] | None = None,
        duration_s: float | None = None,
        warm_up_s: float | None = None,
        time_step_s: float | None = None,
    ) -> RigResponse:
        """Sensor signals of the linear model on one track realization (constant speed).

        Same time grid, axle inputs and sensor averaging as :class:`~susp_bo.rig.Rig`
        so that both can be compared sample for sample. The inputs are treated as
        periodic over the run (FFT); the warm-up absorbs the wrap-around transient.
        """
        from susp_bo.rig.simulator import excitation_for_run

        sim = self.spec.simulation
        duration = sim.duration_s if duration_s is None else duration_s
        warm = sim.warm_up_s if warm_up_s is None else warm_up_s
        dt = sim.time_step_s if time_step_s is None else time_step_s
        system = self._system(parameters, speed_m_s)
        total = warm + duration
        key = (
            id(geometry),
            float(speed_m_s),
            total,
            dt,
            system.assembly.axle_positions_m.tobytes(),
        )
        periodic = system.assembly.periodic_inputs
        cached = self._input_cache.get(key)
        if periodic.size == 0 and cached is not None and cached[0] is geometry:
            spectrum, rate_spectrum = cached[1]
            n_t, per_sample = cached[2]
        else:
            excitation, per_sample = excitation_for_run(
                system.assembly, geometry, speed_m_s, total, dt, sim.sample_rate_hz
            )
            n_t = excitation.time_s.size
            spectrum = scipy.fft.rfft(_input_matrix(excitation), axis=1)  # (n_in x F)
            rate_spectrum = scipy.fft.rfft(_input_matrix(excitation, rates=True), axis=1)
            if periodic.size == 0:
                if len(self._input_cache) >= 16:
                    self._input_cache.pop(next(iter(self._input_cache)))
                self._input_cache[key] = (geometry, (spectrum, rate_spectrum), (n_t, per_sample))
        freqs = scipy.fft.rfftfreq(n_t, dt)
        omega = 2 * np.pi * freqs
        n = system.n_dofs
        assembly = system.assembly
        # sensor velocity (C) and gravity pick-up (C) signals, solved in modal coordinates
        rows = np.vstack(
            [
                assembly.sensor_acceleration @ np.eye(n, system.a.shape[0], n),
                assembly.sensor_displacement @ np.eye(n, system.a.shape[0]),
            ]
        )
        outputs = _solve_outputs(
            system, self._modal_basis(system), rows, spectrum, rate_spectrum, omega
        )
        signals_t = scipy.fft.irfft(outputs, n=n_t, axis=1)
        start = round(warm / (dt * per_sample)) * per_sample
        n_channels = len(assembly.channels)
        velocity = signals_t[:n_channels, start::per_sample].T
        position = signals_t[n_channels:, start::per_sample].T
        interval = per_sample * dt
        acceleration = np.diff(velocity, axis=0) / interval
        pickup = 0.5 * (position[1:] + position[:-1])
        time = (np.arange(acceleration.shape[0]) + 0.5) * interval
        signals = np.ascontiguousarray((acceleration + pickup).T)
        return RigResponse(
            time + start * dt,
            assembly.channels,
            signals,
            sim.sample_rate_hz,
            self.spec.spectrum,
        )


def _input_matrix(excitation: AxleExcitation, rates: bool = False) -> FloatArray:
    """Axle inputs in assembly order ``[vertical, cross_level, alignment]`` per axle."""
    names = (
        ("vertical_rate_m_s", "cross_level_rate_rad_s", "alignment_rate_m_s")
        if rates
        else ("vertical_m", "cross_level_rad", "alignment_m")
    )
    arrays = [getattr(excitation, name) for name in names]  # each (n_axles x n_t)
    return np.stack(arrays, axis=1).reshape(-1, excitation.time_s.size)


def _band_average(psd: FloatArray, bin_width_hz: float, edges_hz: FloatArray) -> FloatArray:
    """Mean of a PSD on Welch bins over each band, bins as cells (as spectra.py)."""
    cell_low = (np.arange(psd.shape[-1]) - 0.5) * bin_width_hz
    overlap = np.minimum(edges_hz[1:, None], cell_low[None, :] + bin_width_hz) - np.maximum(
        edges_hz[:-1, None], cell_low[None, :]
    )
    weights = np.clip(overlap, 0.0, None) / np.diff(edges_hz)[:, None]
    return psd @ weights.T
