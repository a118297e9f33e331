"""Extension point for optional physical effects (carbody bending, wheel out-of-roundness, …).

A rig file may carry ``[effects.<name>]`` tables (parsed into ``RigSpec.effects``).
Each name must be registered here with a function that adds its elements or
coordinates to the assembly builder; both the PyBullet world and the linearised
model are built from that assembly, so an effect is added once and appears in
both. The library of candidate effects lives in :mod:`susp_bo.discrepancy.effects`
and registers itself here; it is imported lazily the first time an effect name
is looked up. An unknown effect name is an error before any simulation runs.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterable
from typing import Any

LIBRARY_MODULE = "susp_bo.discrepancy.effects"

EffectHook = Callable[[Any, Any, dict[str, Any]], None]
"""``hook(spec, builder, options)``: mutate the assembly builder for one effect."""

_REGISTRY: dict[str, EffectHook] = {}


def register_effect(name: str) -> Callable[[EffectHook], EffectHook]:
    """Decorator registering ``hook`` as the implementation of effect ``name``."""

    def decorate(hook: EffectHook) -> EffectHook:
        if name in _REGISTRY:
            raise ValueError(f"effect {name!r} is already registered")
        _REGISTRY[name] = hook
        return hook

    return decorate


def _load_library() -> None:
    """Import the library of candidate effects (it registers its hooks on import)."""
    importlib.import_module(LIBRARY_MODULE)


def available_effects() -> tuple[str, ...]:
    """Names of the registered effects (the library included), sorted."""
    _load_library()
    return tuple(sorted(_REGISTRY))


def check_effect_names(names: Iterable[str]) -> None:
    """Refuses an effect name that is not registered (the library loaded first).

    Args:
        names: the effect names of a rig (``[effects.<name>]``), enabled or not.

    Raises:
        ValueError: ``"[effects.<name>]: unknown effect '<name>' (did you mean 'x'?);
            allowed effects: …"``.
    """
    from susp_bo.rig.schema import did_you_mean

    unknown = [name for name in names if name not in _REGISTRY]
    if unknown:
        _load_library()
    for name in unknown:
        if name not in _REGISTRY:
            allowed = available_effects()
            raise ValueError(
                f"[effects.{name}]: unknown effect {name!r}{did_you_mean(name, allowed)}; "
                f"allowed effects: {', '.join(allowed) or '(none registered)'}"
            )


def apply_effects(spec: Any, builder: Any) -> None:
    """Apply every effect of ``spec.effects`` whose table has ``enabled`` true (default true).

    Raises:
        ValueError: an effect name that is not registered.
    """
    for name, options in getattr(spec, "effects", {}).items():
        if not options.get("enabled", True):
            continue
        if name not in _REGISTRY:
            _load_library()
        if name not in _REGISTRY:
            raise ValueError(
                f"rig effect {name!r}: not available; registered effects: "
                f"{', '.join(available_effects()) or '(none yet)'}"
            )
        _REGISTRY[name](spec, builder, dict(options))
