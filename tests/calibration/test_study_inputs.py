"""Study input helpers: what a refused resume says about the store it would not reuse."""

from __future__ import annotations

import json

from susp_bo.calibration.study_inputs import fingerprint_change


def test_a_changed_fingerprint_shows_what_changed() -> None:
    """The stored and current values were both cut at 37 characters, before the part that
    differed, so a changed sigma printed two identical values."""
    common = {"noise_m_s2": 0.01, "sample_rate_hz": 200.0, "n_samples": [2000]}
    stored = json.dumps({**common, "model_error_sigma": None})
    now = json.dumps({**common, "model_error_sigma": [0.05, 0.05]})
    assert fingerprint_change(stored, now) == "model_error_sigma: stored null, now [0.05, 0.05]"
    order = fingerprint_change('["a_damping", "b_stiffness"]', '["b_stiffness", "a_damping"]')
    assert order.startswith("the same entries in another order") and "order must be" in order
    digest = fingerprint_change("sha256:" + "0" * 40 + "abc" * 10, "sha256:" + "0" * 40 + "abd")
    assert digest == "stored '...0000000000abcabcabcabcabcabcabcabcabcabc', now '...0000000000abd'"
    # a long value differing past the cut was shown twice the same (second review)
    long_old = json.dumps({"sigma": [0.1] * 12 + [0.1234]})
    long_new = json.dumps({"sigma": [0.1] * 12 + [0.1235]})
    assert fingerprint_change(long_old, long_new) == (
        "sigma: stored ..., 0.1, 0.1234], now ..., 0.1, 0.1235]"
    )
    assert fingerprint_change('["x"]', '["y"]') == "stored '[\"x\"]', now '[\"y\"]'"
