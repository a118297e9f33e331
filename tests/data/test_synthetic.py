"""synthesize_runs: a bad seed is refused naming it, before any simulation."""

from __future__ import annotations

import pytest

from susp_bo.data.synthetic import synthesize_runs
from susp_bo.rig.spec import load_rig_spec


@pytest.mark.parametrize("seed", [-1, 1.5, None, True, "3"])
def test_a_bad_seed_is_refused_naming_it(seed: object) -> None:
    """-1, 1.5 and None gave numpy's SeedSequence errors, which do not name the argument."""
    spec = load_rig_spec("hst_trailer")
    with pytest.raises(ValueError, match=rf"^seed: got {seed!r}; expected an integer >= 0$"):
        synthesize_runs(spec, nu=1, seed=seed)  # type: ignore[arg-type]
