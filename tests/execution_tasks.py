"""Top-level task functions for tests/test_execution.py.

They live in a plain module (not a test module) because worker processes of a
``spawn`` pool import a task function by its module name; the tests put this
folder on ``sys.path`` first (spawned workers inherit the parent's sys.path).
"""

from __future__ import annotations

import os

import numpy as np


class Diverged(RuntimeError):
    """Stands in for the rig's SimulationFailed: an exception with a ``reason``."""

    def __init__(self, reason: str) -> None:
        super().__init__(f"simulation failed: {reason}")
        self.reason = reason


def log_spectrum(seed: int, n_samples: int) -> np.ndarray:
    """A deterministic small 'simulation': log-amplitude spectrum (n_samples // 2 + 1,) of a
    seeded, low-pass filtered random signal, float64."""
    signal = np.random.default_rng(seed).standard_normal(n_samples)
    filtered = np.convolve(signal, np.hanning(9) / np.hanning(9).sum(), mode="same")
    return np.log(np.abs(np.fft.rfft(filtered)) + 1e-12)


def misbehaving(seed: int, mode: str) -> np.ndarray:
    """``log_spectrum(seed, 64)`` when mode is "ok"; raises Diverged for "raise";
    kills its process for "exit" (as a segfaulting simulator would)."""
    if mode == "exit":
        os._exit(1)
    if mode == "raise":
        raise Diverged(f"carbody roll diverged for seed {seed}")
    return log_spectrum(seed, 64)


def crash_once(seed: int, marker_folder: str) -> np.ndarray:
    """Kills its process the first time it runs for this seed (a transient crash, like an
    OOM kill), then behaves as ``log_spectrum(seed, 64)``."""
    marker = os.path.join(marker_folder, f"crashed-{seed}")
    if not os.path.exists(marker):
        with open(marker, "w"):
            pass
        os._exit(1)
    return log_spectrum(seed, 64)


def sleep_then_return(seconds: float) -> float:
    """A long task: sleeps ``seconds`` (s) in the worker, returns them."""
    import time

    time.sleep(seconds)
    return seconds
