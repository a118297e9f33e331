"""A linear-Gaussian stand-in for the rig under the summary likelihood (shared by
``test_summary_misfit`` and ``test_fit_rules``): a run's spectrum y = m0 + G w + e,
e ~ N(0, Σ) with shared "track" factors across every channel and band (the toy of
``test_track_statistics``)."""

from __future__ import annotations

import numpy as np

C, F, Q = 3, 12, 2
NU, MU = 3, 3
M = 100


def toy(seed: int = 0, channels: int = C, bands: int = F, q: int = Q):
    """(m0 (p,), G (p x q), chol Σ (p x p)), p = channels x bands: two shared track factors
    (they move the spectra partly as the parameters do: what makes bins taken as
    independent overconfident) plus 0.05 independent noise per bin."""
    rng = np.random.default_rng(seed)
    p = channels * bands
    m0 = rng.normal(0.0, 1.0, p)
    g = rng.normal(0.0, 0.05, (p, q))
    loading = 3.0 * g @ rng.standard_normal((q, 2)) + 0.05 * rng.standard_normal((p, 2))
    sigma = loading @ loading.T + 0.05**2 * np.eye(p)
    return m0, g, np.linalg.cholesky(sigma)


def toy_runs(rng, m0, g, chol, w, n, effect=None, shape=(C, F)):
    """(n x channels x bands) runs at w (plus a fixed ``effect`` (p,) the model does not
    have), ``shape`` = (channels, bands)."""
    e = rng.standard_normal((n, len(m0))) @ chol.T
    extra = 0.0 if effect is None else effect
    return (m0 + g @ w + extra + e).reshape(n, *shape)


def effect_of_a_missing_mode(chol: np.ndarray) -> np.ndarray:
    """(C x F) a rise of the last channel's four highest bands by 2 track sd per bin (a
    mode the model lacks)."""
    sd = np.sqrt(np.diag(chol @ chol.T)).reshape(C, F)
    effect = np.zeros((C, F))
    effect[-1, -4:] = 2.0 * sd[-1, -4:]
    return effect
