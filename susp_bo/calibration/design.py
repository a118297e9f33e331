"""Step 1: space-filling design of the admissible set C_w, and unit-cube scaling.

C_w is a box (2 x q bounds). All surrogate work happens in the unit cube
u = (w − lower) / (upper − lower); :func:`to_unit` and :func:`from_unit` convert.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import torch
from scipy.stats import qmc

DesignMethod = Literal["sobol", "lhs"]


def check_bounds(bounds: np.ndarray) -> np.ndarray:
    """Validates (2 x q) bounds (finite, upper > lower) and returns them as float64."""
    b = np.asarray(bounds, dtype=np.float64)
    if b.ndim != 2 or b.shape[0] != 2 or b.shape[1] < 1:
        raise ValueError(f"bounds: shape {b.shape}, expected (2 x q) with q >= 1")
    if not np.all(np.isfinite(b)) or np.any(b[1] <= b[0]):
        raise ValueError(f"bounds: {b.tolist()} must be finite with upper > lower")
    return b


def to_unit(w: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Physical units (n x q) -> unit cube (n x q)."""
    return (np.asarray(w, dtype=np.float64) - bounds[0]) / (bounds[1] - bounds[0])


def from_unit(u: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """Unit cube (n x q) -> physical units (n x q)."""
    return bounds[0] + np.asarray(u, dtype=np.float64) * (bounds[1] - bounds[0])


def default_design_size(q: int) -> int:
    """Initial design size: 5 q points, at least 10 (a small multiple of q)."""
    return max(10, 5 * q)


def sobol_first_point(engine: torch.quasirandom.SobolEngine) -> np.ndarray:
    """The first point (q,) of a fresh scrambled ``engine``, independent of torch's default
    dtype: its scrambling shift / 2^MAXBIT, rounded to float32 (what ``draw`` returns under
    torch's float32 default), as float64."""
    if engine.num_generated != 0:
        raise ValueError("engine: has drawn points already; its first point is gone")
    shift = engine.shift.to(torch.float32) / float(2**engine.MAXBIT)
    return shift.to(torch.float64).numpy()


def space_filling_design(
    n: int, bounds: np.ndarray, seed: int, method: DesignMethod = "sobol"
) -> np.ndarray:
    """Space-filling design of n points in the box, in physical units.

    Args:
        n: number of points (>= 1).
        bounds: (2 x q) lower and upper bounds.
        seed: seed of the scrambling (Sobol) or of the permutations (LHS).
        method: "sobol" (Owen-scrambled Sobol' sequence, first n points) or "lhs"
            (Latin hypercube optimised for centred discrepancy).

    The same design whatever torch's default dtype: torch's ``SobolEngine`` computes the
    sequence's first point in the default dtype when it is built (float32 unless the
    caller changed it; the other points in the dtype asked for), so a program that had
    called ``torch.set_default_dtype(torch.float64)`` got another first point, and so
    another calibration, than ``susp-bo``. The first point is computed here explicitly,
    rounded to float32 as torch's own default gives it: the design every recorded result
    of this tool was computed with (:func:`sobol_first_point`).

    Returns:
        (n x q) design in physical units.
    """
    b = check_bounds(bounds)
    if n < 1:
        raise ValueError(f"n: {n} must be >= 1")
    q = b.shape[1]
    if method == "sobol":
        engine = torch.quasirandom.SobolEngine(dimension=q, scramble=True, seed=seed)
        first = sobol_first_point(engine)
        unit = engine.draw(n, dtype=torch.float64).numpy()
        unit[0] = first
    elif method == "lhs":
        sampler = qmc.LatinHypercube(d=q, optimization="random-cd", rng=np.random.default_rng(seed))
        unit = sampler.random(n)
    else:
        raise ValueError(f"method: {method!r}, expected 'sobol' or 'lhs'")
    return from_unit(unit, b)
