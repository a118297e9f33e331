"""From a rig spec to bodies, coordinates, force elements, contact and sensors.

The ``two_bogie_car`` topology: a carbody, two bogie frames (front, rear) and
four wheelsets (1 = leading). Carbody and bogie frames have five coordinates
each (lateral y, vertical z, roll, pitch, yaw); the longitudinal motion is that
of the moving frame. Wheelsets have lateral y and yaw dynamic; their vertical
position and roll follow the rails (inputs). Kinematics are linearised about
the nominal pose (small rotations), force laws are not (see elements.py).

Track inputs ``x(t)`` (n_in = 3 per axle): ``[vertical, cross_level, alignment]``
of each axle, axles in order 1…4.

Both the PyBullet world and the linearised model are built from the
:class:`Assembly`, so they share every element definition.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from susp_bo.rig.builder import (
    DOFS_OF_KIND,
    RIGID_DOFS,
    WHEELSET_DOFS,
    AssemblyBuilder,
    Body,
    PeriodicInputs,
)
from susp_bo.rig.components import component_value
from susp_bo.rig.contact import WheelRailContact
from susp_bo.rig.effects import apply_effects
from susp_bo.rig.elements import Dampers, DeadBands, SeriesDampers, Springs

FloatArray = NDArray[np.float64]
GRAVITY_M_S2 = 9.81
INPUTS_PER_AXLE = ("vertical", "cross_level", "alignment")

_REQUIRED = {
    "carbody": ("mass", "roll_inertia", "pitch_inertia", "yaw_inertia", "cg_height"),
    "bogie": (
        "mass",
        "roll_inertia",
        "pitch_inertia",
        "yaw_inertia",
        "cg_height",
        "half_pivot_spacing",
        "half_wheelbase",
    ),
    "wheelset": ("mass", "yaw_inertia", "rolling_radius"),
    "primary": (
        "longitudinal_stiffness",
        "lateral_stiffness",
        "vertical_stiffness",
        "vertical_damping",
        "vertical_damper_slope_ratio",
        "vertical_damper_knee",
        "lateral_half_spacing",
        "height",
    ),
    "secondary": (
        "longitudinal_stiffness",
        "lateral_stiffness",
        "vertical_stiffness",
        "lateral_half_spacing",
        "height",
        "vertical_damping",
        "vertical_damper_half_spacing",
        "lateral_damping",
        "lateral_damper_slope_ratio",
        "lateral_damper_knee",
    ),
    "yaw_damper": (
        "damping",
        "series_stiffness",
        "slope_ratio",
        "knee",
        "lateral_half_spacing",
        "height",
    ),
    "anti_roll_bar": ("stiffness",),
    "bump_stop": ("stiffness", "gap", "smoothing"),
    "contact": (
        "longitudinal_creep_coefficient",
        "lateral_creep_coefficient",
        "equivalent_conicity",
        "half_contact_spacing",
        "flange_gap",
        "flange_stiffness",
        "flange_smoothing",
    ),
}


_OPTIONAL = {"wheelset": ("roll_inertia", "spin_inertia")}
"""Named parameters a rig may define (defaults derived from the required ones)."""


def allowed_parameters(topology: str) -> dict[str, tuple[str, ...]]:
    """Keys each parameter section of a rig of this topology may hold (required + optional)."""
    required_parameters(topology)  # checks the topology
    return {section: (*keys, *_OPTIONAL.get(section, ())) for section, keys in _REQUIRED.items()}


def required_parameters(topology: str) -> tuple[str, ...]:
    """Named parameters a rig of this topology must define."""
    if topology != "two_bogie_car":
        raise ValueError(f"rig topology: got {topology!r}; supported: 'two_bogie_car'")
    return tuple(f"{section}_{key}" for section, keys in _REQUIRED.items() for key in keys)


@dataclass(frozen=True)
class Assembly:
    """Everything the world and the linear model need, in matrix form.

    Attributes:
        bodies: the bodies, in coordinate order.
        dof_names: ``<body>.<coordinate>`` (n,).
        mass_diagonal: generalised masses and inertias (n,).
        axle_positions_m: axle positions from the car centre, + forward (n_axles,).
        springs, dampers, dead_bands, series: the force element groups.
        contact: the wheel–rail contact.
        sensor_acceleration: sensor rows on q̈ (C x n).
        sensor_displacement: sensor rows on q (gravity pick-up, C x n), m/s² per unit.
        channels: sensor names (C,).
        periodic_inputs: deterministic inputs added to the track inputs (e.g. wheel
            out-of-roundness): ``x_i += A cos(k s(t) + φ)`` with ``s`` the travelled
            distance (m).
    """

    bodies: tuple[Body, ...]
    dof_names: tuple[str, ...]
    mass_diagonal: FloatArray
    axle_positions_m: FloatArray
    springs: Springs
    dampers: Dampers
    dead_bands: DeadBands
    series: SeriesDampers
    contact: WheelRailContact
    sensor_acceleration: FloatArray
    sensor_displacement: FloatArray
    channels: tuple[str, ...]
    periodic_inputs: PeriodicInputs = field(default_factory=lambda: PeriodicInputs.empty())

    @property
    def n_dofs(self) -> int:
        """Number of generalised coordinates n."""
        return len(self.dof_names)

    @property
    def n_inputs(self) -> int:
        """Number of track inputs n_in (3 per axle)."""
        return len(INPUTS_PER_AXLE) * len(self.axle_positions_m)

    def body(self, name: str) -> Body:
        """The body called ``name``."""
        for body in self.bodies:
            if body.name == name:
                return body
        raise KeyError(f"no body {name!r}; bodies: {', '.join(b.name for b in self.bodies)}")


def _bodies(p: dict[str, float]) -> tuple[list[Body], FloatArray]:
    bodies: list[Body] = []
    index = 0

    def add(
        name: str,
        kind: str,
        cg: tuple[float, float, float],
        mass: float,
        inertia: tuple[float, float, float],
    ) -> None:
        nonlocal index
        count = len(RIGID_DOFS) if kind == "rigid" else len(WHEELSET_DOFS)
        bodies.append(Body(name, kind, cg, mass, inertia, tuple(range(index, index + count))))
        index += count

    add(
        "carbody",
        "rigid",
        (0.0, 0.0, p["carbody_cg_height"]),
        p["carbody_mass"],
        (p["carbody_roll_inertia"], p["carbody_pitch_inertia"], p["carbody_yaw_inertia"]),
    )
    pivot = p["bogie_half_pivot_spacing"]
    for name, x in (("bogie_front", pivot), ("bogie_rear", -pivot)):
        add(
            name,
            "rigid",
            (x, 0.0, p["bogie_cg_height"]),
            p["bogie_mass"],
            (p["bogie_roll_inertia"], p["bogie_pitch_inertia"], p["bogie_yaw_inertia"]),
        )
    half_wheelbase = p["bogie_half_wheelbase"]
    axles = np.array(
        [
            pivot + half_wheelbase,
            pivot - half_wheelbase,
            -pivot + half_wheelbase,
            -pivot - half_wheelbase,
        ]
    )
    radius = p["wheelset_rolling_radius"]
    roll = p.get("wheelset_roll_inertia", p["wheelset_yaw_inertia"])
    spin = p.get("wheelset_spin_inertia", 0.1 * p["wheelset_yaw_inertia"])
    for a, x in enumerate(axles):
        add(
            f"wheelset_{a + 1}",
            "wheelset",
            (float(x), 0.0, radius),
            p["wheelset_mass"],
            (roll, spin, p["wheelset_yaw_inertia"]),
        )
    return bodies, axles


def build_assembly(spec: object, parameters: dict[str, float] | None = None) -> Assembly:
    """The vehicle of a :class:`~susp_bo.rig.spec.RigSpec` in matrix form.

    Args:
        spec: the rig spec.
        parameters: named parameter values to use instead of ``spec.parameters``
            (already validated by ``RigSpec.with_parameters``). A per-component name
            ``<parameter>@<component>`` (:mod:`susp_bo.rig.components`) sets that one
            element (group); every other element takes the shared ``<parameter>``.
    """
    p = dict(spec.parameters if parameters is None else parameters)  # type: ignore[attr-defined]

    def of(name: str, component: str) -> float:  # per-component override, else shared
        return component_value(p, name, component)

    bodies, axles = _bodies(p)
    builder = AssemblyBuilder(bodies, len(INPUTS_PER_AXLE) * len(axles))
    builder.axle_of = {f"wheelset_{a + 1}": a for a in range(len(axles))}
    half_wheelbase = p["bogie_half_wheelbase"]
    for bogie in ("bogie_front", "bogie_rear"):
        xb = builder.bodies[bogie].cg_m[0]
        # primary suspension, per axlebox
        for a, xa in enumerate(axles):
            if abs(xa - xb) > half_wheelbase + 1e-9:
                continue
            wheelset = f"wheelset_{a + 1}"
            for side, sign in (("left", 1.0), ("right", -1.0)):
                at = (float(xa), sign * p["primary_lateral_half_spacing"], p["primary_height"])
                box = f"{wheelset}_{side}"
                tag = f"primary_{box}"
                for axis, key in (("x", "longitudinal"), ("y", "lateral"), ("z", "vertical")):
                    builder.add(
                        "spring",
                        f"{tag}_{axis}",
                        wheelset,
                        bogie,
                        at,
                        axis,
                        stiffness=of(f"primary_{key}_stiffness", box),
                    )
                builder.add(
                    "damper",
                    f"{tag}_vertical_damper",
                    wheelset,
                    bogie,
                    at,
                    "z",
                    damping=of("primary_vertical_damping", box),
                    slope_ratio=of("primary_vertical_damper_slope_ratio", box),
                    knee=of("primary_vertical_damper_knee", box),
                )
        # secondary suspension
        h2 = p["secondary_height"]
        for side, sign in (("left", 1.0), ("right", -1.0)):
            at = (xb, sign * p["secondary_lateral_half_spacing"], h2)
            bogie_side = f"{bogie}_{side}"
            tag = f"secondary_{bogie_side}"
            for axis, key in (("x", "longitudinal"), ("y", "lateral"), ("z", "vertical")):
                builder.add(
                    "spring",
                    f"{tag}_{axis}",
                    bogie,
                    "carbody",
                    at,
                    axis,
                    stiffness=of(f"secondary_{key}_stiffness", bogie_side),
                )
            at_damper = (xb, sign * p["secondary_vertical_damper_half_spacing"], h2)
            builder.add(
                "damper",
                f"{tag}_vertical_damper",
                bogie,
                "carbody",
                at_damper,
                "z",
                damping=of("secondary_vertical_damping", bogie_side),
                slope_ratio=1.0,
                knee=np.inf,
            )
            at_yaw = (xb, sign * p["yaw_damper_lateral_half_spacing"], p["yaw_damper_height"])
            builder.add(
                "series",
                f"yaw_damper_{bogie}_{side}",
                bogie,
                "carbody",
                at_yaw,
                "x",
                stiffness=of("yaw_damper_series_stiffness", bogie_side),
                damping=of("yaw_damper_damping", bogie_side),
                slope_ratio=of("yaw_damper_slope_ratio", bogie_side),
                knee=of("yaw_damper_knee", bogie_side),
            )
        builder.add(
            "damper",
            f"secondary_{bogie}_lateral_damper",
            bogie,
            "carbody",
            (xb, 0.0, h2),
            "y",
            damping=of("secondary_lateral_damping", bogie),
            slope_ratio=of("secondary_lateral_damper_slope_ratio", bogie),
            knee=of("secondary_lateral_damper_knee", bogie),
        )
        builder.add(
            "dead_band",
            f"bump_stop_{bogie}",
            bogie,
            "carbody",
            (xb, 0.0, h2),
            "y",
            stiffness=of("bump_stop_stiffness", bogie),
            gap=of("bump_stop_gap", bogie),
            smoothing=of("bump_stop_smoothing", bogie),
        )
        roll_row = np.zeros(builder.n)
        roll_row[builder.bodies["carbody"].dofs[2]] += 1.0
        roll_row[builder.bodies[bogie].dofs[2]] -= 1.0
        builder.add_rows(
            "spring",
            f"anti_roll_bar_{bogie}",
            roll_row,
            np.zeros(builder.n_inputs),
            stiffness=of("anti_roll_bar_stiffness", bogie),
        )
    for a in range(len(axles)):  # flange contact: dead band on wheelset-track lateral offset
        wheelset = builder.bodies[f"wheelset_{a + 1}"]
        g = np.zeros(builder.n)
        h = np.zeros(builder.n_inputs)
        g[wheelset.dofs[0]] = 1.0
        h[3 * a + 2] = -1.0
        builder.add_rows(
            "dead_band",
            f"flange_{wheelset.name}",
            g,
            h,
            stiffness=p["contact_flange_stiffness"],
            gap=p["contact_flange_gap"],
            smoothing=p["contact_flange_smoothing"],
        )
    apply_effects(spec, builder)  # extension point: optional physical effects
    return _finish(builder, list(builder.bodies.values()), axles, p, spec)


def _finish(
    builder: AssemblyBuilder,
    bodies: list[Body],
    axles: FloatArray,
    p: dict[str, float],
    spec: object,
) -> Assembly:
    spring_group, spring_p = builder.group("spring")
    damper_group, damper_p = builder.group("damper")
    dead_group, dead_p = builder.group("dead_band")
    series_group, series_p = builder.group("series")
    wheelsets = [b for b in bodies if b.kind == "wheelset"]
    contact = WheelRailContact(
        lateral_dof=np.array([b.dofs[0] for b in wheelsets]),
        yaw_dof=np.array([b.dofs[1] for b in wheelsets]),
        alignment_input=np.array([3 * a + 2 for a in range(len(wheelsets))]),
        longitudinal_creep=p["contact_longitudinal_creep_coefficient"],
        lateral_creep=p["contact_lateral_creep_coefficient"],
        conicity=p["contact_equivalent_conicity"],
        rolling_radius=p["wheelset_rolling_radius"],
        half_contact_spacing=p["contact_half_contact_spacing"],
    )
    sensors = spec.sensors  # type: ignore[attr-defined]
    acceleration = np.zeros((len(sensors), builder.n))
    displacement = np.zeros((len(sensors), builder.n))
    for row, sensor in enumerate(sensors):
        if sensor.body not in builder.bodies or builder.bodies[sensor.body].kind != "rigid":
            rigid = [b.name for b in bodies if b.kind == "rigid"]
            raise ValueError(
                f"[[sensors]] entry {row + 1} ({sensor.name!r}): body {sensor.body!r} is not "
                f"allowed; allowed bodies: {', '.join(rigid)} (a sensor sits on a rigid body)"
            )
        axis = "z" if sensor.direction == "vertical" else "y"
        acceleration[row], _ = builder.point_rows(sensor.body, sensor.position_m, axis)
        if axis == "y":  # specific force in the body frame: gravity picked up through roll
            displacement[row, builder.bodies[sensor.body].dofs[2]] = GRAVITY_M_S2
    names = tuple(f"{b.name}.{d}" for b in bodies for d in DOFS_OF_KIND[b.kind])
    mass = np.concatenate(
        [
            [b.mass, b.mass, *b.inertia]
            if b.kind == "rigid"
            else ([b.mass, b.inertia[2]] if b.kind == "wheelset" else [b.mass])
            for b in bodies
        ]
    )
    periodic = builder.periodic
    periodic_inputs = (
        PeriodicInputs(
            np.array([e[0] for e in periodic], dtype=np.intp),
            np.array([e[1] for e in periodic]),
            np.array([e[2] for e in periodic]),
            np.array([e[3] for e in periodic]),
        )
        if periodic
        else PeriodicInputs.empty()
    )
    return Assembly(
        bodies=tuple(bodies),
        dof_names=names,
        mass_diagonal=mass.astype(np.float64),
        axle_positions_m=axles,
        springs=Springs(spring_group, spring_p.get("stiffness", np.zeros(0))),
        dampers=Dampers(
            damper_group,
            damper_p.get("damping", np.zeros(0)),
            damper_p.get("slope_ratio", np.zeros(0)),
            damper_p.get("knee", np.zeros(0)),
        ),
        dead_bands=DeadBands(
            dead_group,
            dead_p.get("stiffness", np.zeros(0)),
            dead_p.get("gap", np.zeros(0)),
            dead_p.get("smoothing", np.zeros(0)),
        ),
        series=SeriesDampers(
            series_group,
            series_p.get("stiffness", np.zeros(0)),
            series_p.get("damping", np.zeros(0)),
            series_p.get("slope_ratio", np.zeros(0)),
            series_p.get("knee", np.zeros(0)),
        ),
        contact=contact,
        sensor_acceleration=acceleration,
        sensor_displacement=displacement,
        channels=tuple(s.name for s in sensors),
        periodic_inputs=periodic_inputs,
    )


def free_wheelset_assembly(spec: object) -> Assembly:
    """A single wheelset on the track with no suspension (Klingel's kinematic oscillation).

    Uses the wheelset and contact parameters of ``spec``; no sensors.
    """
    p = dict(spec.parameters)  # type: ignore[attr-defined]
    body = Body(
        "wheelset_1",
        "wheelset",
        (0.0, 0.0, p["wheelset_rolling_radius"]),
        p["wheelset_mass"],
        (
            p.get("wheelset_roll_inertia", p["wheelset_yaw_inertia"]),
            p.get("wheelset_spin_inertia", 0.0),
            p["wheelset_yaw_inertia"],
        ),
        (0, 1),
    )
    builder = AssemblyBuilder([body], len(INPUTS_PER_AXLE))
    builder.add_rows(
        "dead_band",
        "flange_wheelset_1",
        np.array([1.0, 0.0]),
        np.array([0.0, 0.0, -1.0]),
        stiffness=p["contact_flange_stiffness"],
        gap=p["contact_flange_gap"],
        smoothing=p["contact_flange_smoothing"],
    )

    class _NoSensors:
        sensors: tuple[object, ...] = ()

    return _finish(builder, [body], np.zeros(1), p, _NoSensors())
