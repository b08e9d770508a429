"""Physics checks that every generated object must pass (PyBullet DIRECT, dt = 1/240 s).

1. **No interpenetration**: body vs functional part over the whole joint range (25 angles plus the
   reset angle); the closest geometric distance must exceed -0.5 mm (resting contact allowed).
   PyBullet reports distances minus both shapes' collision margins (1 mm each); we add them back.
2. **The joint reaches the task's success threshold** under a position motor whose force cap is the
   joint friction plus a hand-sized torque (``DRIVE_TORQUE``): faucet |q| > 1.5 rad in both
   directions, laptop / toilet q >= target, bucket bail upright (|q| < 0.3 * pi/2, i.e. DexArt's
   progress > 0.7). For the bucket, a moving ``JOINT_POINT2POINT`` constraint at the bail apex (a
   stand-in for the hand, capped at ``LIFT_FORCE``) first swings the bail upright (1 s), then pulls
   0.5 m up (2 s) and holds (1 s); at the end the body must have risen more than 0.25 m with the bail
   upright (DexArt's bucket success).
3. **Passive stillness**: released at the reset angle with the friction motor on, nothing moves for
   2 s (joint drift < 0.01 rad, root drift < 2 mm; the bucket stands on a ground plane). Laptop and
   toilet lids are also released at 6 openings across the range and must hold within 0.01 rad for 1 s.

The arm-reach check is geometric and lives in ``placement.py``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from dexart_lite.registration import SPECS
from dexart_lite.sim import BulletClient, pybullet

DT = 1.0 / 240.0  # s
FAUCET_SUCCESS = SPECS["faucet"].success["angle"]  # rad, |q| beyond this counts (DexArt)
BUCKET_UPRIGHT = 0.3 * math.pi / 2  # rad, |q| below this is DexArt's bucket progress > 0.7 (SPECS' threshold)
BUCKET_LIFT = SPECS["bucket"].success["lift"]  # m, DexArt's bucket success height
DRIVE_TORQUE = {"faucet": 1.0, "laptop": 2.0, "toilet": 2.0, "bucket": 0.5}  # N*m on top of friction
LIFT_FORCE = 60.0  # N, cap of the point-to-point "hand" constraint
LIFT_HEIGHT = 0.5  # m, how far the hand pulls the bail apex up
PENETRATION_TOL = 5e-4  # m
HOLD_TOL = 0.01  # rad
ROOT_DRIFT_TOL = 0.002  # m


@dataclass
class CheckResult:
    """Measured numbers from :func:`check`; ``failures`` is empty when the object passes."""

    min_clearance: float  # m, closest body-part distance over the joint range (< 0: penetration)
    reached: float  # rad: faucet min(q+, -q-) reached; laptop/toilet max q; bucket final |q| (motor)
    passive_drift: float  # rad, joint drift over 2 s at the reset angle
    root_drift: float  # m, root displacement over 2 s
    hold_drift: float | None = None  # rad, laptop/toilet: worst drift after release at 6 openings
    lift: float | None = None  # m, bucket: body rise when pulled by the bail apex
    lift_bail_q: float | None = None  # rad, bucket: bail angle at the end of the lift
    failures: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        return {k: (round(v, 4) if isinstance(v, float) else v) for k, v in asdict(self).items()}


def new_client() -> BulletClient:
    client = BulletClient(connection_mode=pybullet.DIRECT)
    client.setGravity(0.0, 0.0, -9.81)
    client.setTimeStep(DT)
    return client


def load(client: BulletClient, urdf: Path, fixed_base: bool) -> int:
    """Load an object with its root frame at the origin; a free body gets a ground plane at z = 0."""
    if not fixed_base:
        client.createMultiBody(0, client.createCollisionShape(pybullet.GEOM_PLANE))
    return client.loadURDF(str(urdf), basePosition=(0.0, 0.0, 0.0), useFixedBase=fixed_base,
                           flags=pybullet.URDF_USE_INERTIA_FROM_FILE)


def joint_angle(client: BulletClient, uid: int) -> float:
    return client.getJointState(uid, 0)[0]


def set_friction(client: BulletClient, uid: int, friction: float) -> None:
    """Joint friction as DexArt-lite applies it: a velocity motor with target 0 and force = friction."""
    client.setJointMotorControl2(uid, 0, pybullet.VELOCITY_CONTROL, targetVelocity=0.0, force=friction)


def root_frame_pose(client: BulletClient, uid: int) -> tuple[tuple, tuple]:
    """World pose (position, quaternion) of the root *link frame*; PyBullet reports the inertial frame."""
    com_pos, com_orn = client.getBasePositionAndOrientation(uid)
    local_pos, local_orn = client.getDynamicsInfo(uid, -1)[3:5]
    inv_pos, inv_orn = client.invertTransform(local_pos, local_orn)
    return client.multiplyTransforms(com_pos, com_orn, inv_pos, inv_orn)


def root_frame_position(client: BulletClient, uid: int) -> np.ndarray:
    return np.array(root_frame_pose(client, uid)[0])


def min_clearance(client: BulletClient, uid: int, angles) -> float:
    """Closest geometric distance (m) between the root and link 0 over joint ``angles`` (< 0: overlap)."""
    margins = client.getDynamicsInfo(uid, -1)[11] + client.getDynamicsInfo(uid, 0)[11]
    worst = 1.0
    for q in angles:
        client.resetJointState(uid, 0, float(q))
        points = client.getClosestPoints(uid, uid, 0.05, linkIndexA=-1, linkIndexB=0)
        worst = min([worst] + [pt[8] + margins for pt in points])
    return worst


def drive(client: BulletClient, uid: int, start: float, target: float, force: float, seconds: float) -> list[float]:
    """Position-motor drive from ``start`` toward ``target``; returns the joint angle at every step."""
    client.resetJointState(uid, 0, start)
    client.setJointMotorControl2(uid, 0, pybullet.POSITION_CONTROL, targetPosition=target, force=force)
    trace = []
    for _ in range(int(seconds / DT)):
        client.stepSimulation()
        trace.append(joint_angle(client, uid))
    return trace


def settle(client: BulletClient, uid: int, start: float, friction: float, seconds: float) -> tuple[float, float]:
    """Release at ``start`` with the friction motor on; returns (joint drift, root drift)."""
    client.resetJointState(uid, 0, start)
    set_friction(client, uid, friction)
    root0 = root_frame_position(client, uid)
    for _ in range(int(seconds / DT)):
        client.stepSimulation()
    return abs(joint_angle(client, uid) - start), float(np.linalg.norm(root_frame_position(client, uid) - root0))


def bucket_lift(client: BulletClient, uid: int, grasp_point, init: float) -> tuple[float, float]:
    """Swing the bail apex upright (1 s), pull it up ``LIFT_HEIGHT`` (2 s), hold (1 s).

    Returns (body rise, bail angle) at the end.
    """
    client.resetJointState(uid, 0, init)
    set_friction(client, uid, 0.0)
    for _ in range(int(0.5 / DT)):  # settle on the ground
        client.stepSimulation()
    # Constraint frames are relative to the link's inertial frame, not the URDF link frame.
    local_pos, local_orn = client.getDynamicsInfo(uid, 0)[3:5]
    inv_pos, inv_orn = client.invertTransform(local_pos, local_orn)
    pivot_in_com = client.multiplyTransforms(inv_pos, inv_orn, list(grasp_point), (0, 0, 0, 1))[0]
    link_pos, link_orn = client.getLinkState(uid, 0, computeForwardKinematics=True)[4:6]
    start = np.array(client.multiplyTransforms(link_pos, link_orn, list(grasp_point), (0, 0, 0, 1))[0])
    root_pos, root_orn = root_frame_pose(client, uid)
    z0 = root_pos[2]
    # The apex when upright: bail frame origin (on the pivot line) + the grasp point in root axes.
    upright = np.array(client.multiplyTransforms(link_pos, root_orn, list(grasp_point), (0, 0, 0, 1))[0])
    cid = client.createConstraint(uid, 0, -1, -1, pybullet.JOINT_POINT2POINT, (0, 0, 0), pivot_in_com,
                                  start.tolist())
    swing, pull, hold = int(1.0 / DT), int(2.0 / DT), int(1.0 / DT)
    for i in range(swing + pull + hold):
        if i < swing:
            goal = start + (upright - start) * (i + 1) / swing
        else:
            goal = upright + [0.0, 0.0, LIFT_HEIGHT * min(1.0, (i + 1 - swing) / pull)]
        client.changeConstraint(cid, goal.tolist(), maxForce=LIFT_FORCE)
        client.stepSimulation()
    return float(root_frame_position(client, uid)[2] - z0), joint_angle(client, uid)


def check(urdf: Path, category: str, joint: dict, grasp_point, fixed_base: bool) -> CheckResult:
    """Run every physics check on one object. ``joint`` holds lower/upper/init/target/friction."""
    lower, upper, init, target, friction = (joint[k] for k in ("lower", "upper", "init", "target", "friction"))
    client = new_client()
    try:
        uid = load(client, urdf, fixed_base)
        clearance = min_clearance(client, uid, list(np.linspace(lower, upper, 25)) + [init])

        base_state = client.saveState()
        force = friction + DRIVE_TORQUE[category]
        if category == "faucet":
            plus = drive(client, uid, init, 2.0, force, 2.0)
            client.restoreState(base_state)
            minus = drive(client, uid, init, -2.0, force, 2.0)
            reached = min(max(plus), -min(minus))
        elif category == "bucket":
            reached = abs(drive(client, uid, init, target, force, 2.0)[-1])
        else:
            reached = max(drive(client, uid, init, min(target + 0.2, upper), force, 2.0))

        client.restoreState(base_state)
        passive, root = settle(client, uid, init, friction, 2.0)
        result = CheckResult(min_clearance=clearance, reached=reached, passive_drift=passive, root_drift=root)

        if category in ("laptop", "toilet"):
            drifts = []
            for q in np.linspace(lower + 0.05, upper - 0.05, 6):
                client.restoreState(base_state)
                drifts.append(settle(client, uid, float(q), friction, 1.0)[0])
            result.hold_drift = max(drifts)
        if category == "bucket":
            client.restoreState(base_state)
            result.lift, result.lift_bail_q = bucket_lift(client, uid, grasp_point, init)
    finally:
        client.disconnect()

    failures = result.failures
    if clearance < -PENETRATION_TOL:
        failures.append(f"interpenetration {clearance * 1000:.1f} mm")
    if category == "faucet" and reached <= FAUCET_SUCCESS:
        failures.append(f"faucet reached only {reached:.2f} rad")
    if category in ("laptop", "toilet") and reached < target:
        failures.append(f"lid reached {reached:.2f} < target {target:.2f} rad")
    if category == "bucket" and reached >= BUCKET_UPRIGHT:
        failures.append(f"bail stayed at {reached:.2f} rad from upright")
    if passive > HOLD_TOL or root > ROOT_DRIFT_TOL:
        failures.append(f"passive drift {passive:.3f} rad / {root * 1000:.1f} mm")
    if result.hold_drift is not None and result.hold_drift > HOLD_TOL:
        failures.append(f"lid does not hold its opening (drift {result.hold_drift:.3f} rad)")
    if result.lift is not None and (result.lift <= BUCKET_LIFT or abs(result.lift_bail_q) >= BUCKET_UPRIGHT):
        failures.append(f"lift {result.lift:.3f} m with the bail at {result.lift_bail_q:.2f} rad")
    return result
