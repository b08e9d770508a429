"""Physics checks that every generated object must pass (PyBullet DIRECT, dt = 1/240 s).

The object is loaded into a ``BulletSim`` by the env's own loader, so the checks see the physics the tasks see
(link damping removed, exact inertias, deterministic contact-pair order).

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

from dexart_lite.pointcloud import quat_to_matrix
from dexart_lite.registration import SPECS
from dexart_lite.sim import BASE_LINK, Body, BulletSim

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


@dataclass
class Rig:
    """One object alone in a ``BulletSim`` (loaded by the env's own loader), its task joint and functional part."""

    sim: BulletSim
    body: Body
    joint: int  # the task joint's index (found by name)
    part: int  # the functional part's link index (the joint's child link)

    def angle(self) -> float:
        """The task joint's angle (rad)."""
        return float(self.sim.joint_states(self.body, [self.joint])[0][0])

    def reset(self, q: float) -> None:
        self.sim.reset_joints(self.body, [self.joint], [float(q)])

    def root_position(self) -> np.ndarray:
        """World position (m) of the root link's URDF frame."""
        return np.array(self.sim.base_frame(self.body)[0])


def load(urdf: Path, joint_name: str, fixed_base: bool) -> Rig:
    """A world at ``DT`` with the object's root frame at the origin; a free body gets a ground plane at z = 0.
    The object is loaded as the env loads it (``BulletSim.load_urdf`` with the file's exact inertias)."""
    sim = BulletSim(dt=DT)
    if not fixed_base:
        sim.create_ground()
    body = sim.load_urdf("object", urdf, fixed_base=fixed_base, inertia_from_file=True)
    joint = body.joint(joint_name)
    return Rig(sim, body, joint, part=joint)  # PyBullet numbers a link like the joint that moves it


def min_clearance(rig: Rig, angles) -> float:
    """Closest geometric distance (m) between the root and the part over joint ``angles`` (< 0: overlap)."""
    worst = 1.0
    for q in angles:
        rig.reset(q)
        distance = rig.sim.closest_distance(rig.body, BASE_LINK, rig.part, within=0.05)
        worst = worst if distance is None else min(worst, distance)
    return worst


def drive(rig: Rig, start: float, target: float, force: float, seconds: float) -> list[float]:
    """Position-motor drive from ``start`` toward ``target`` (rad) with at most ``force`` (N*m); returns the joint
    angle at every step."""
    rig.reset(start)
    rig.sim.position_motors(rig.body, [rig.joint], [target], [0.0], [force])
    trace = []
    for _ in range(int(seconds / DT)):
        rig.sim.step()
        trace.append(rig.angle())
    return trace


def settle(rig: Rig, start: float, friction: float, seconds: float) -> tuple[float, float]:
    """Release at ``start`` with the friction motor on (as the env applies joint friction); returns (joint drift,
    root drift)."""
    rig.reset(start)
    rig.sim.friction_motor(rig.body, rig.joint, friction)
    root0 = rig.root_position()
    rig.sim.step(int(seconds / DT))
    return abs(rig.angle() - start), float(np.linalg.norm(rig.root_position() - root0))


def bucket_lift(rig: Rig, grasp_point, init: float) -> tuple[float, float]:
    """Swing the bail apex upright (1 s), pull it up ``LIFT_HEIGHT`` (2 s), hold (1 s).

    Returns (body rise, bail angle) at the end.
    """
    rig.reset(init)
    rig.sim.friction_motor(rig.body, rig.joint, 0.0)
    rig.sim.step(int(0.5 / DT))  # settle on the ground
    grasp = np.asarray(grasp_point, dtype=float)  # m, in the bail's frame
    (link_pos,), (link_quat,) = rig.sim.link_frames(rig.body, [rig.part])
    start = link_pos + quat_to_matrix(link_quat) @ grasp
    root_pos, root_quat = rig.sim.base_frame(rig.body)
    z0 = root_pos[2]
    # The apex when upright: bail frame origin (on the pivot line) + the grasp point in root axes.
    upright = link_pos + quat_to_matrix(np.array(root_quat)) @ grasp
    pin = rig.sim.pin_point(rig.body, rig.part, grasp, start)
    swing, pull, hold = int(1.0 / DT), int(2.0 / DT), int(1.0 / DT)
    for i in range(swing + pull + hold):
        if i < swing:
            goal = start + (upright - start) * (i + 1) / swing
        else:
            goal = upright + [0.0, 0.0, LIFT_HEIGHT * min(1.0, (i + 1 - swing) / pull)]
        rig.sim.move_pin(pin, goal.tolist(), max_force=LIFT_FORCE)
        rig.sim.step()
    return float(rig.root_position()[2] - z0), rig.angle()


def check(urdf: Path, category: str, joint: dict, grasp_point, fixed_base: bool) -> CheckResult:
    """Run every physics check on one object. ``joint`` holds name/lower/upper/init/target/friction."""
    lower, upper, init, target, friction = (joint[k] for k in ("lower", "upper", "init", "target", "friction"))
    rig = load(urdf, joint["name"], fixed_base)
    try:
        clearance = min_clearance(rig, list(np.linspace(lower, upper, 25)) + [init])

        base_state = rig.sim.save_state()
        force = friction + DRIVE_TORQUE[category]
        if category == "faucet":
            plus = drive(rig, init, 2.0, force, 2.0)
            rig.sim.restore_state(base_state)
            minus = drive(rig, init, -2.0, force, 2.0)
            reached = min(max(plus), -min(minus))
        elif category == "bucket":
            reached = abs(drive(rig, init, target, force, 2.0)[-1])
        else:
            reached = max(drive(rig, init, min(target + 0.2, upper), force, 2.0))

        rig.sim.restore_state(base_state)
        passive, root = settle(rig, init, friction, 2.0)
        result = CheckResult(min_clearance=clearance, reached=reached, passive_drift=passive, root_drift=root)

        if category in ("laptop", "toilet"):
            drifts = []
            for q in np.linspace(lower + 0.05, upper - 0.05, 6):
                rig.sim.restore_state(base_state)
                drifts.append(settle(rig, float(q), friction, 1.0)[0])
            result.hold_drift = max(drifts)
        if category == "bucket":
            rig.sim.restore_state(base_state)
            result.lift, result.lift_bail_q = bucket_lift(rig, grasp_point, init)
    finally:
        rig.sim.close()

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
