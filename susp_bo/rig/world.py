"""The PyBullet world: the vehicle as one multibody on a moving frame.

The base of the multibody is fixed to a frame that moves with the train, so
the track passes underneath and nothing is translated at 83 m/s. Each body's
coordinates are joints of the multibody: carbody and bogie frames hang on a
chain ``prismatic y → prismatic z → revolute roll (x) → pitch (y) → yaw (z)``
through massless links, the wheelsets on ``prismatic y → revolute yaw``; the
last link of a chain carries the body's mass and principal inertia at its
centre of gravity. Elastic modal coordinates added by effects (carbody bending)
are one prismatic joint each carrying the generalised mass. The joint
coordinates are then exactly the generalised coordinates ``q`` of the
assembly, read with one ``getJointStates`` call and
driven with one ``setJointMotorControlArray(TORQUE_CONTROL)`` call per step.

PyBullet settings (DESIGN.md pitfalls): one DIRECT client per world, gravity
off (the model is written about the static equilibrium; gravity enters the
sensors), velocity motors disabled (force 0), linear/angular/joint damping 0
on every link and the base, sleeping disabled, no collision shapes, fixed
step with one sub-step; joint torques last one step and are re-applied.
"""

from __future__ import annotations

import contextlib

from susp_bo.rig._pybullet import direct_client, pybullet
from susp_bo.rig.assembly import Assembly

_RIGID_CHAIN = (
    (pybullet.JOINT_PRISMATIC, (0.0, 1.0, 0.0)),
    (pybullet.JOINT_PRISMATIC, (0.0, 0.0, 1.0)),
    (pybullet.JOINT_REVOLUTE, (1.0, 0.0, 0.0)),
    (pybullet.JOINT_REVOLUTE, (0.0, 1.0, 0.0)),
    (pybullet.JOINT_REVOLUTE, (0.0, 0.0, 1.0)),
)
_WHEELSET_CHAIN = (
    (pybullet.JOINT_PRISMATIC, (0.0, 1.0, 0.0)),
    (pybullet.JOINT_REVOLUTE, (0.0, 0.0, 1.0)),
)
# an elastic modal coordinate (e.g. carbody bending): one prismatic joint carrying the
# generalised mass; its coupling to the vehicle is entirely in the element rows.
_MODAL_CHAIN = ((pybullet.JOINT_PRISMATIC, (0.0, 0.0, 1.0)),)
_CHAINS = {"rigid": _RIGID_CHAIN, "wheelset": _WHEELSET_CHAIN, "modal": _MODAL_CHAIN}


class VehicleWorld:
    """One PyBullet DIRECT client holding the vehicle multibody.

    Args:
        time_step_s: fixed step (s).
    """

    def __init__(self, time_step_s: float) -> None:
        self.client = direct_client()  # no "argv[0]=" banner in the output
        self.time_step_s = float(time_step_s)
        self.body_id = -1
        self.joints: list[int] = []

    def build(self, assembly: Assembly) -> None:
        """(Re)create the vehicle from an assembly, at rest in the nominal pose."""
        c = self.client
        c.resetSimulation()
        c.setGravity(0.0, 0.0, 0.0)
        c.setPhysicsEngineParameter(
            fixedTimeStep=self.time_step_s, numSubSteps=1, deterministicOverlappingPairs=1
        )
        masses, inertias, parents, types, axes, positions = [], [], [], [], [], []
        for body in assembly.bodies:
            chain = _CHAINS[body.kind]
            parent = 0  # the base (moving frame)
            for i, (joint_type, axis) in enumerate(chain):
                last = i == len(chain) - 1
                masses.append(body.mass if last else 0.0)
                inertias.append(body.inertia if last else (0.0, 0.0, 0.0))
                parents.append(parent)
                types.append(joint_type)
                axes.append(axis)
                positions.append(body.cg_m if i == 0 else (0.0, 0.0, 0.0))
                parent = len(masses)
        n = len(masses)
        if n != assembly.n_dofs:  # pragma: no cover - guards the chain definitions
            raise RuntimeError(f"world: {n} joints for {assembly.n_dofs} coordinates")
        identity = (0.0, 0.0, 0.0, 1.0)
        self.body_id = c.createMultiBody(
            baseMass=0.0,
            baseCollisionShapeIndex=-1,
            baseVisualShapeIndex=-1,
            basePosition=(0.0, 0.0, 0.0),
            linkMasses=masses,
            linkCollisionShapeIndices=[-1] * n,
            linkVisualShapeIndices=[-1] * n,
            linkPositions=positions,
            linkOrientations=[identity] * n,
            linkInertialFramePositions=[(0.0, 0.0, 0.0)] * n,
            linkInertialFrameOrientations=[identity] * n,
            linkParentIndices=parents,
            linkJointTypes=types,
            linkJointAxis=axes,
        )
        for link in range(-1, n):
            c.changeDynamics(
                self.body_id,
                link,
                linearDamping=0.0,
                angularDamping=0.0,
                jointDamping=0.0,
                activationState=pybullet.ACTIVATION_STATE_DISABLE_SLEEPING,
            )
            if link >= 0:
                c.changeDynamics(
                    self.body_id, link, mass=masses[link], localInertiaDiagonal=inertias[link]
                )
        self.joints = list(range(n))
        c.setJointMotorControlArray(
            self.body_id, self.joints, pybullet.VELOCITY_CONTROL, forces=[0.0] * n
        )

    def set_state(self, q: list[float], qdot: list[float]) -> None:
        """Reset joint positions and velocities (n,)."""
        for joint, (position, velocity) in enumerate(zip(q, qdot)):
            self.client.resetJointState(self.body_id, joint, float(position), float(velocity))

    def close(self) -> None:
        """Disconnect the client (idempotent)."""
        if self.body_id is not None and self.client is not None:
            with contextlib.suppress(pybullet.error):  # already disconnected
                self.client.disconnect()
        self.client = None  # type: ignore[assignment]
        self.body_id = None  # type: ignore[assignment]
