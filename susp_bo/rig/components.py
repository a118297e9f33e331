"""Per-component parameters: one element (or one group) instead of every element of a type.

A type-level named parameter such as ``yaw_damper_damping`` sets all four yaw
dampers. A *per-component* name ``<parameter>@<component>`` overrides it for one
element (or one group of elements that act as one component)::

    yaw_damper_damping@bogie_front_left        # the left yaw damper of the front bogie
    secondary_vertical_damping@bogie_rear_right
    primary_vertical_damping@wheelset_1_left   # the vertical damper of one axlebox
    secondary_lateral_damping@bogie_front      # the lateral damper of one bogie

The component is the element's tag without the type prefix (``yaw_damper_{bogie}_{side}``
→ ``{bogie}_{side}``; ``primary_wheelset_N_{side}`` → ``wheelset_N_{side}``). A
per-component name is a plain string with no spaces, quotes or commas, so it travels
unchanged through TOML (``name = "yaw_damper_damping@bogie_front_left"``; as a table key
it must be quoted), JSON result files, the CLI's ``--parameters a,b``, the evaluation
store's fingerprint and figure labels/file names.

The value of the override wins over the shared parameter for that component only (so
an override *pins* its component: changing the shared value no longer moves it);
without any override every element takes the shared value, so results are bit-for-bit
those of the type-level model. Overrides are given through ``RigSpec.with_parameters``,
parameter files (``--truth``/``--params``) and ``[[calibration.parameters]]`` entries
(their reference, default the shared value, becomes the override); the rig file's
parameter sections hold type-level values only. Which parameters have a per-component
form, and their components: :func:`component_parameters` (topology ``two_bogie_car``).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from susp_bo.rig.schema import did_you_mean

COMPONENT_SEPARATOR = "@"
"""Separates the type-level parameter from the component: ``<parameter>@<component>``."""

BOGIES = ("bogie_front", "bogie_rear")
SIDES = ("left", "right")
BOGIE_SIDES = tuple(f"{bogie}_{side}" for bogie in BOGIES for side in SIDES)
AXLEBOXES = tuple(f"wheelset_{axle}_{side}" for axle in range(1, 5) for side in SIDES)

_BY_GROUP: dict[tuple[str, ...], tuple[str, ...]] = {
    # one component per axlebox: springs (x, y, z) and the vertical damper
    AXLEBOXES: (
        "primary_longitudinal_stiffness",
        "primary_lateral_stiffness",
        "primary_vertical_stiffness",
        "primary_vertical_damping",
        "primary_vertical_damper_slope_ratio",
        "primary_vertical_damper_knee",
    ),
    # one component per bogie side: air spring (x, y, z), vertical damper, yaw damper
    BOGIE_SIDES: (
        "secondary_longitudinal_stiffness",
        "secondary_lateral_stiffness",
        "secondary_vertical_stiffness",
        "secondary_vertical_damping",
        "yaw_damper_damping",
        "yaw_damper_series_stiffness",
        "yaw_damper_slope_ratio",
        "yaw_damper_knee",
    ),
    # one component per bogie: lateral damper, anti-roll bar, lateral bump stop
    BOGIES: (
        "secondary_lateral_damping",
        "secondary_lateral_damper_slope_ratio",
        "secondary_lateral_damper_knee",
        "anti_roll_bar_stiffness",
        "bump_stop_stiffness",
        "bump_stop_gap",
        "bump_stop_smoothing",
    ),
}


def component_parameters(topology: str = "two_bogie_car") -> dict[str, tuple[str, ...]]:
    """Type-level parameters that have a per-component form -> their components.

    Args:
        topology: the rig topology (only ``two_bogie_car``).

    Raises:
        ValueError: another topology.
    """
    if topology != "two_bogie_car":
        raise ValueError(f"rig topology: got {topology!r}; supported: 'two_bogie_car'")
    return {name: group for group, names in _BY_GROUP.items() for name in names}


def is_component_name(name: str) -> bool:
    """Whether ``name`` has the per-component form ``<parameter>@<component>``."""
    return COMPONENT_SEPARATOR in name


def component_name(parameter: str, component: str) -> str:
    """``<parameter>@<component>`` (validated, see :func:`split_component_name`)."""
    name = f"{parameter}{COMPONENT_SEPARATOR}{component}"
    split_component_name(name)
    return name


def split_component_name(
    name: str,
    known: Iterable[str] | None = None,
    topology: str = "two_bogie_car",
) -> tuple[str, str]:
    """Check a per-component name and split it into ``(parameter, component)``.

    Args:
        name: ``<parameter>@<component>``, e.g. ``yaw_damper_damping@bogie_front_left``.
        known: the rig's named parameters (for a did-you-mean on the parameter part);
            None = the parameters that have a per-component form.
        topology: the rig topology.

    Raises:
        ValueError: naming the value and what is allowed: not of the form
            ``<parameter>@<component>``; a parameter that is unknown or has no
            per-component form; a component that the parameter does not have (with
            the valid components and the closest one).
    """
    forms = component_parameters(topology)
    parts = name.split(COMPONENT_SEPARATOR)
    if len(parts) != 2 or not parts[0] or not parts[1]:
        raise ValueError(
            f"parameter {name!r}: a per-component name is <parameter>@<component> with one "
            f"{COMPONENT_SEPARATOR!r}, e.g. 'yaw_damper_damping@bogie_front_left'"
        )
    parameter, component = parts
    known = list(forms) if known is None else [k for k in known if not is_component_name(k)]
    if parameter not in known:
        raise ValueError(
            f"parameter {name!r}: {parameter!r} is not a named parameter of the rig"
            f"{did_you_mean(parameter, known)}; parameters with a per-component form: "
            f"{', '.join(forms)}"
        )
    if parameter not in forms:
        raise ValueError(
            f"parameter {name!r}: {parameter!r} has no per-component form (it is one value "
            f"for the whole car); parameters with one: {', '.join(forms)}"
        )
    components = forms[parameter]
    if component not in components:
        raise ValueError(
            f"parameter {name!r}: unknown component {component!r} of {parameter}"
            f"{did_you_mean(component, components)}; valid components: {', '.join(components)}"
        )
    return parameter, component


def component_value(p: Mapping[str, float], parameter: str, component: str) -> float:
    """The value of ``parameter`` for one component: its override if given, else the shared one.

    Args:
        p: named parameter values (type-level and per-component).
        parameter: the type-level name, e.g. ``yaw_damper_damping``.
        component: e.g. ``bogie_front_left``.
    """
    return p.get(f"{parameter}{COMPONENT_SEPARATOR}{component}", p[parameter])
