"""``DexArtEnv``: the scene and the one step loop shared by the four tasks.

A task (``faucet.py``, ``bucket.py``, ``laptop.py``, ``toilet.py``) only sets class constants
(robot base, camera, crop, randomisation) and fills four hooks: ``progress``, ``stage``,
``is_success`` and ``reward_terms``. It never overrides ``step``, whose order is fixed:

    act -> simulate -> read one State snapshot -> evaluate (info) -> observe -> reward

Reward, success and the observation's state vector are pure functions of the snapshot. The reward
is returned as named terms in ``info["reward_terms"]`` and the reward is their sum.

Frames: world z up, table top at z = 0; the robot base sits at ``ROBOT_BASE`` facing +x with the
identity orientation, so robot-base coordinates are world coordinates minus ``ROBOT_BASE``.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from dexart_lite import objects as objects_lib
from dexart_lite import pointcloud as pc
from dexart_lite.articulated import PART_LINK, ArticulatedObjects
from dexart_lite.camera import CameraPose, viewpoint
from dexart_lite.envs import rewards
from dexart_lite.objects import ObjectInfo
from dexart_lite.robot import (ACTION_DIM, ARM_LINKS, FINGER_GROUPS, MAX_LINEAR_SPEED, SYNERGIES, Robot, RobotState,
                               synergy_targets)
from dexart_lite.sensor import PointCloudSensor, SensorConfig
from dexart_lite.registration import (HAND_MODES, HORIZON, OBSERVATIONS, PRIVILEGED_STATE, STATE_ONLY_PRIVILEGED,
                                      TaskSpec, privileged_vector)  # HORIZON: control steps per episode (the registered max_episode_steps)
from dexart_lite.sim import BASE_LINK, BulletSim
from dexart_lite.utils import check_choice

GROUPS = tuple(FINGER_GROUPS)  # ("thumb", "index", "middle", "ring", "palm")
CONTACT_IMPULSE = 0.01  # N*s summed over a link pair's contact points (DexArt), i.e. 2.5 N at dt 0.004
MAX_JOINT_SPEED = 99.0  # rad/s; PyBullet clamps joint speeds at 100: reaching it means the solver lost control
MAX_OBJECT_SPEED = 10.0  # m/s
TABLE_HALF_EXTENTS = (0.65, 0.65, 0.025)  # m, top surface at z = 0
TABLE_RGBA, PEDESTAL_RGBA = (0.8, 0.75, 0.65, 1.0), (0.5, 0.5, 0.5, 1.0)
VIEWER_SIZE = (320, 240)  # px, env.render()

CONTROL_DT = 0.04  # s: one control step (DexArt's 25 Hz) = dt * frame_skip at the defaults (0.004 s x 10)


def physics_setting(text: str) -> dict:
    """``"20x10"`` (solver iterations x sub-steps per control step) -> the env keywords
    ``{"solver_iterations": 20, "frame_skip": 10, "dt": 0.004}``; the control step stays ``CONTROL_DT``.
    The defaults are ``"50x10"`` (``benchmarks/perf/bench_physics.py`` checks cheaper ones)."""
    iterations, sep, skip = text.partition("x")
    try:
        iterations, skip = int(iterations), int(skip)
    except ValueError:
        iterations = skip = 0
    if not sep or iterations < 1 or skip < 1:
        raise ValueError(f"a physics setting is ITERATIONSxFRAME_SKIP with both >= 1 (e.g. 20x10), got {text!r}")
    return {"solver_iterations": iterations, "frame_skip": skip, "dt": CONTROL_DT / skip}


@dataclass(frozen=True)
class State:
    """One reading of the simulation after a control step (world frame, SI units)."""

    t: int  # control steps taken in this episode
    horizon: int
    obj: ObjectInfo
    robot: RobotState
    flange_delta: np.ndarray  # (3,) m, link6 displacement over the step
    commanded_velocity: np.ndarray  # (3,) m/s, the linear twist asked for
    control_dt: float  # s
    palm_x_axis: np.ndarray  # (3,) palm normal of base_link in world
    palm_z_prev: float  # m, palm height one step earlier
    q: float  # rad, task joint
    qd: float  # rad/s
    handle_pos: np.ndarray  # (3,) the functional part's grasp point
    base_pos: np.ndarray  # (3,) object root frame
    base_pos_at_reset: np.ndarray  # (3,)
    base_linvel: np.ndarray  # (3,) m/s
    base_angvel: np.ndarray  # (3,) rad/s
    part_contact: np.ndarray  # (5,) bool per GROUPS, touching the functional part
    body_contact: np.ndarray  # (5,) bool per GROUPS, touching the object's root link
    arm_contacts: int  # arm links touching any object link
    unstable: bool  # non-finite or runaway values were read

    @property
    def dist(self) -> float:
        """Palm (base_link origin) to grasp point, m."""
        return float(np.linalg.norm(self.robot.palm_pos - self.handle_pos))

    @property
    def n_fingers(self) -> int:
        """Finger groups (thumb, index, middle, ring) touching the functional part."""
        return int(self.part_contact[:4].sum())

    @property
    def palm_contact(self) -> bool:
        return bool(self.part_contact[4])


class DexArtEnv(gym.Env):
    """Base class of the four tasks; see the module docstring. Keyword arguments:

    split: "seen", "unseen" or "seen_half"; object_names: explicit list instead of a split;
    camera: override of the camera pose, a ``CameraPose`` or ``{"eye": [...], "target": [...]}``;
    num_points, imagination, point_noise, camera_noise: point-cloud settings (``SensorConfig``);
    view_range: ``(azimuth, polar)`` half-widths in degrees of a random camera viewpoint drawn at every
    reset on DexArt's viewpoint sphere (``camera.viewpoint``); None (default): the fixed camera;
    observation: "cloud" (DexArt's: point cloud + state) or "state" (a diagnostic, not DexArt's: the state
    vector with the privileged object state appended, ``privileged_state``, and no camera render at all);
    reward: "dexart" (DexArt's terms), "shaped" (plus ``rewards.shaping``'s stage-2 terms, not DexArt's),
    "capped" (the terminal bonus counts progress up to the success threshold only, ``bonus``; not DexArt's) or
    "flat" (a success pays a fixed horizon * 1.2 * threshold, whatever the step; not DexArt's);
    hand: "joints" (DexArt's 22-D action: twist + 16 hand joint targets) or "synergy" (not DexArt's: a 9-D
    action, twist + 3 hand synergies, ``robot.synergy_targets``; the env turns it into the 22-D one);
    depth_image: also observe the camera's metric depth image, ``obs["depth_image"]`` (64, 64) float32 m
    (0 where nothing is hit), the input of the 2-D baseline (not part of DexArt's observation);
    randomize: DexArt's object pose randomisation; dt, frame_skip, solver_iterations: physics;
    render_mode: None or "rgb_array".
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 25}
    # ---- filled in by each task: its SPEC (registration.SPECS) sets the next four (``__init_subclass__``)
    SPEC: TaskSpec
    CATEGORY: str = ""
    ROBOT_BASE: tuple = ()  # m, world
    PEDESTAL: tuple | None = None  # (centre, half extents) of the box the robot stands on, m
    CAMERA: CameraPose
    VIEWER: CameraPose
    CROP: tuple = ()  # (xmin, xmax, ymin, ymax, zmin, zmax), m, robot-base frame
    RAND_POS: float = 0.0  # m, one-sided uniform [0, RAND_POS) on x, y and z (as DexArt)
    RAND_YAW: float = 0.0  # rad, uniform [-RAND_YAW, RAND_YAW]
    TERMINATE_ON_SUCCESS: bool = True
    # False: ``step`` skips the observation (the camera render) and returns the last one again, for the
    # guide steps of a start-state curriculum (rl/curriculum.py), which no learner sees; reset always observes
    observe_steps: bool = True
    EXTRA_STATE: int = 0  # length of extra_state()
    REBUILD_EVERY: int = 200  # resets between two builds of the simulation (see reset)

    def __init_subclass__(cls, **kwargs):
        """A task's name, robot base and reset randomisation come from its ``SPEC``, written down once."""
        super().__init_subclass__(**kwargs)
        if "SPEC" in cls.__dict__:
            cls.CATEGORY, cls.ROBOT_BASE = cls.SPEC.name, cls.SPEC.robot_base
            cls.RAND_POS, cls.RAND_YAW = cls.SPEC.rand_pos, np.deg2rad(cls.SPEC.rand_yaw_deg)

    def __init__(self, split: str = "seen", object_names=None, camera=None, num_points: int = 512,
                 imagination: bool = True, point_noise: bool = False, camera_noise: bool = False,
                 view_range=None, depth_image: bool = False, randomize: bool = True, dt: float = 0.004, frame_skip: int = 10, solver_iterations: int = 50,
                 reward: str = "dexart", observation: str = "cloud", hand: str = "joints",
                 render_mode: str | None = None, **unknown):
        if unknown:
            valid = [n for n in inspect.signature(DexArtEnv.__init__).parameters if n not in ("self", "unknown")]
            raise ValueError(f"unknown keyword(s) {sorted(unknown)}; valid keywords: {', '.join(valid)}")
        check_choice("render_mode", render_mode, [None, "rgb_array"])
        if object_names is None:
            infos = objects_lib.list_objects(self.CATEGORY, split)
        else:
            infos = [objects_lib.get_object(n) for n in object_names]
            for info in infos:
                check_choice(f"{self.CATEGORY} object", info.name,
                             [o.name for s in objects_lib.FOLDERS for o in objects_lib.list_objects(self.CATEGORY, s)])
        if num_points < 1 or frame_skip < 1 or dt <= 0:
            raise ValueError("num_points and frame_skip must be >= 1 and dt > 0")
        check_choice("reward", reward, rewards.REWARD_MODES)
        check_choice("observation", observation, OBSERVATIONS)
        check_choice("hand", hand, HAND_MODES)
        self.reward_mode, self.observation, self.hand_mode = reward, observation, hand
        self.render_mode, self.randomize, self.frame_skip = render_mode, randomize, int(frame_skip)
        self.control_dt = dt * frame_skip
        self._physics = dict(dt=dt, solver_iterations=solver_iterations)
        self._object_infos = infos
        self._nominal_camera = self._camera_pose(camera)
        if view_range is not None:
            try:
                view_range = tuple(float(np.deg2rad(float(v))) for v in view_range)
            except (TypeError, ValueError):
                view_range = ()
            if len(view_range) != 2 or not all(np.isfinite(v) and v >= 0 for v in view_range):
                raise ValueError("view_range must be (azimuth, polar) half-widths in degrees, both >= 0")
        corners = [self._nominal_camera] if view_range is None else \
            [viewpoint(self._nominal_camera, a, p) for a in (-view_range[0], view_range[0])
             for p in (-view_range[1], view_range[1])]
        # Scenery cropped away and unable to hide anything is not drawn (it would cost render time only).
        self._draw_scenery = any(self._scenery_can_occlude(pose) for pose in corners)
        # Every place the camera's eye can be (m, world): a grid over the viewpoint range, for ``_arm_links_out_of_view``.
        self._eyes = np.array([self._nominal_camera.position]) if view_range is None else np.array(
            [viewpoint(self._nominal_camera, a, p).position for a in np.linspace(-view_range[0], view_range[0], 13)
             for p in np.linspace(-view_range[1], view_range[1], 5)])
        self.sensor_config = SensorConfig(num_points=num_points, imagination=imagination, point_noise=point_noise,
                                          camera_noise=camera_noise, view_range=view_range,
                                          depth_image=bool(depth_image))
        self.sim = None
        self._build_world()
        self._contact_force = CONTACT_IMPULSE / dt  # N
        n_pts = self.sensor_config.total_points
        if observation == "state":  # the diagnostic: the privileged object state instead of any camera
            self.observation_space = spaces.Dict({
                "state": spaces.Box(-np.inf, np.inf, (self.state_dim + PRIVILEGED_STATE,), np.float32)})
        else:
            self.observation_space = spaces.Dict({
                "point_cloud": spaces.Box(-np.inf, np.inf, (n_pts, 3), np.float32),
                "imagined_mask": spaces.MultiBinary(n_pts),
                "state": spaces.Box(-np.inf, np.inf, (self.state_dim,), np.float32),
            })
        if depth_image and observation == "cloud":
            intr = self.sensor_config.intrinsics
            self.observation_space["depth_image"] = spaces.Box(0.0, np.inf, (intr.height, intr.width), np.float32)
        action_dim = ACTION_DIM if hand == "joints" else 6 + len(SYNERGIES)
        self.action_space = spaces.Box(-1.0, 1.0, (action_dim,), np.float32)
        self._state: State | None = None
        self._obs: dict | None = None

    def _build_world(self) -> None:
        """A new simulation holding the scenery and the robot (objects come and go per episode), and
        everything bound to it: segmentation labels, objects, sensor, and the snapshot every reset
        restores. Called at construction and every ``REBUILD_EVERY`` resets (see ``reset``)."""
        first = self.sim is None
        if not first:
            self.sim.close()
        self.sim = BulletSim(**self._physics)
        self.scenery = [self.sim.create_box("table", TABLE_HALF_EXTENTS, (0, 0, -TABLE_HALF_EXTENTS[2]),
                                            rgba=TABLE_RGBA)]
        if self.PEDESTAL is not None:
            self.scenery.append(self.sim.create_box("pedestal", self.PEDESTAL[1], self.PEDESTAL[0], rgba=PEDESTAL_RGBA))
        if not self._draw_scenery:
            self._show_scenery(False)
        self.robot = Robot(self.sim, self.ROBOT_BASE, control_dt=self.control_dt)
        # Arm links that can never matter to the cloud are not drawn either (the depth image of the 2-D
        # baseline shows the whole frame, so there every link is drawn).
        self._undrawn_links = [] if self.sensor_config.depth_image else self._arm_links_out_of_view()
        self._show_undrawn_links(False)
        self.labels = pc.LabelTable()
        for name, link in self.robot.body.links.items():
            self.labels.set(self.robot.body.uid, link, pc.ARM if name in ARM_LINKS or link == BASE_LINK else pc.HAND)
        self.objects = ArticulatedObjects(self.sim, self._object_infos, self.labels, check=first)
        self.sensor = PointCloudSensor(self.sim, self.sensor_config, self._nominal_camera, self.CROP,
                                       self.ROBOT_BASE, self.labels, self.robot.body)
        self._group_of = {k: GROUPS.index(g) for g, ks in self.robot.group_links.items() for k in ks}
        self._arm_links = set(self.robot.arm_links)
        self._initial_state = self.sim.save_state()  # every reset starts from here (replayable)
        self._resets_in_world = 0

    # ------------------------------------------------------------------ task hooks
    def progress(self, s: State) -> float:
        raise NotImplementedError

    def stage(self, s: State) -> int:
        raise NotImplementedError

    def is_success(self, s: State) -> bool:
        raise NotImplementedError

    def reward_terms(self, s: State, stage: int, progress: float, success: bool) -> dict[str, float]:
        raise NotImplementedError

    def bonus(self, s: State, progress: float, threshold: float) -> float:
        """The terminal bonus paid on success; ``threshold`` is the progress success needs, where
        reward="capped" stops counting and which sets reward="flat"'s fixed bonus (``rewards.terminal_bonus``)."""
        return rewards.terminal_bonus(s, progress, threshold, self.reward_mode)

    def extra_state(self, s: State) -> list[float]:
        """Task-specific entries of the state vector, before t / horizon (bucket: palm-up)."""
        return []

    @property
    def state_dim(self) -> int:
        return ACTION_DIM + 3 + 3 + 3 + self.EXTRA_STATE + 1  # qpos, palm lin/ang vel, palm pos, extra, t/T

    # ------------------------------------------------------------------ gymnasium API
    @property
    def horizon(self) -> int:
        return self.spec.max_episode_steps if self.spec is not None and self.spec.max_episode_steps else HORIZON

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = dict(options or {})
        name = options.pop("object", None)
        if options:
            raise ValueError(f"unknown reset option(s) {sorted(options)}; valid: object")
        rng = self.np_random
        if name is None:
            name = self.objects.names[int(rng.integers(len(self.objects.names)))]
        check_choice("object", name, self.objects.names)
        info = self.objects.infos[name]
        # Exact replay. Bullet keeps state of a body that saveState/restoreState do not cover (most
        # likely its broadphase pairs and contact manifolds), and with every object loaded once and the inactive
        # ones parked far away, an episode depended on the episodes before it (a faucet's first step
        # differed by 0.034 rad after a reset on another faucet; gymnasium's determinism check failed
        # on toilets on another CPU). So the world holds no object between episodes: the previous
        # one is removed (its pairs and manifolds with it), the snapshot is restored and the new
        # object loaded (~0.3-1.5 ms). Loading leaks the parsed shapes inside PyBullet (~140 kB per
        # toilet load, freed only with the client), so every REBUILD_EVERY resets the whole world is
        # built again (~0.07 s); a rebuilt world replays the same episodes (it is a fresh env's world).
        self._resets_in_world += 1
        if self._resets_in_world > self.REBUILD_EVERY:
            self._build_world()
            self._resets_in_world = 1
        self.objects.remove_active()
        self.sim.restore_state(self._initial_state)
        # restoreState resets the saved contact points but keeps contact manifolds made since (with
        # their warm-start impulses); a collision pass in the restored configuration drops those.
        self.sim.detect_collisions()
        self.sim.restore_state(self._initial_state)
        position, yaw = np.add(self.ROBOT_BASE, info.position), info.yaw
        if self.randomize:
            position = position + rng.random(3) * self.RAND_POS
            yaw = yaw + rng.uniform(-self.RAND_YAW, self.RAND_YAW)
        self.objects.activate(name, position, yaw)
        self.robot.reset()
        self.sensor.reset(rng)
        self._t = 0
        self._base_at_reset = self.objects.base_state()[0]
        self._state = self.read_state(np.zeros(ACTION_DIM), flange_before=None)
        info_dict = self.evaluate_state(self._state)
        self._obs = self._observe(self._state, info_dict)
        return self._obs, info_dict

    def step(self, action):
        if self._state is None:
            raise RuntimeError("call reset() before step()")
        action = self._joint_action(self._check_action(action))  # (22,) whatever the hand mode
        before = self._state
        self.robot.apply_action(action, before.robot.qpos)
        for i in range(self.frame_skip):
            self.robot.track_arm((i + 1) * self.sim.dt)
            self.sim.step()
        self._t += 1
        state = self.read_state(action, flange_before=before.robot.flange_pos, palm_z_prev=before.robot.palm_pos[2])
        info = self.evaluate_state(state)
        if state.unstable:  # end the episode; never emit the non-finite reading
            info["reward_terms"] = {k: 0.0 for k in info["reward_terms"]}
            info["success"], info["point_labels"] = False, self._labels
            return self._obs, 0.0, False, True, info
        self._state = state
        if self.observe_steps or self.observation == "state":
            self._obs = self._observe(state, info)
        else:  # a guide step whose observation nobody reads (rl/curriculum.py): no camera render, the last
            self._obs = {k: v.copy() for k, v in self._obs.items()}  # observation again (new arrays)
            info["point_labels"] = self._labels = self._labels.copy()
        reward = float(sum(info["reward_terms"].values()))
        return self._obs, reward, bool(info["success"] and self.TERMINATE_ON_SUCCESS), False, info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        camera = self.sensor.camera
        pose, hidden = camera.pose, self._scenery_hidden
        camera.set_pose(self.VIEWER)
        self._show_scenery(True)
        self._show_undrawn_links(True)
        try:
            return camera.render_rgb(*VIEWER_SIZE)
        finally:
            camera.set_pose(pose)
            self._show_scenery(not hidden)
            self._show_undrawn_links(False)

    def close(self):
        if getattr(self, "sim", None) is not None:
            self.sim.close()

    # ------------------------------------------------------------------ the loop's pieces
    _scenery_hidden = False

    def _check_action(self, action) -> np.ndarray:
        action = np.asarray(action, dtype=np.float64)
        if action.shape != self.action_space.shape:
            raise ValueError(f"action must have shape {self.action_space.shape} (hand={self.hand_mode!r}), "
                             f"got {action.shape}")
        if not np.all(np.isfinite(action)):
            raise ValueError(f"action has non-finite entries at indices {np.flatnonzero(~np.isfinite(action)).tolist()}")
        return np.clip(action, -1.0, 1.0)

    def _joint_action(self, action: np.ndarray) -> np.ndarray:
        """The 22-D action (twist + 16 hand joint actions) of a checked action of this env's hand mode."""
        if self.hand_mode == "joints":
            return action
        return np.concatenate([action[:6], self.robot.hand_action(synergy_targets(action[6:]))])

    @property
    def state(self) -> State | None:
        """The simulation as the last ``reset`` or ``step`` read it (None before the first reset): the step
        count ``t``, the object ``obj``, the part's joint ``q`` / ``qd``, the robot, the contacts. A frozen
        dataclass: reading it changes nothing. Experts and benchmarks read the env through it."""
        return self._state

    def read_state(self, action: np.ndarray, flange_before, palm_z_prev: float | None = None) -> State:
        """A fresh reading of the simulation (it changes nothing): what ``step`` does after the physics.
        ``action``: the (22,) action just applied; ``flange_before`` / ``palm_z_prev``: the last reading's
        flange position (m, or None at reset) and palm height (m)."""
        robot = self.robot.read()
        q, qd = self.objects.joint_state()
        base_pos, base_lin, base_ang = self.objects.base_state()
        part, body = np.zeros(len(GROUPS), bool), np.zeros(len(GROUPS), bool)
        arm_links = set()
        for (link_a, link_b), force in self.sim.contact_forces(self.robot.body, self.objects.body).items():
            if force < self._contact_force:
                continue
            if link_a in self._arm_links:
                arm_links.add(link_a)
            elif link_a in self._group_of:
                (part if link_b == PART_LINK else body)[self._group_of[link_a]] = True
        unstable = not (np.all(np.isfinite(robot.qpos)) and np.all(np.isfinite(robot.qvel)) and np.isfinite(q)
                        and np.all(np.isfinite(base_pos)) and np.abs(robot.qvel).max() < MAX_JOINT_SPEED
                        and abs(qd) < MAX_JOINT_SPEED and np.linalg.norm(base_lin) < MAX_OBJECT_SPEED)
        return State(
            t=self._t, horizon=self.horizon, obj=self.objects.active, robot=robot,
            flange_delta=np.zeros(3) if flange_before is None else robot.flange_pos - flange_before,
            commanded_velocity=action[:3] * MAX_LINEAR_SPEED, control_dt=self.control_dt,
            palm_x_axis=pc.quat_to_matrix(robot.palm_quat)[:, 0],
            palm_z_prev=robot.palm_pos[2] if palm_z_prev is None else palm_z_prev,
            q=q, qd=qd, handle_pos=self.objects.handle_position(), base_pos=base_pos,
            base_pos_at_reset=self._base_at_reset, base_linvel=base_lin, base_angvel=base_ang,
            part_contact=part, body_contact=body, arm_contacts=len(arm_links), unstable=bool(unstable))

    def evaluate_state(self, s: State) -> dict:
        """Stage, progress, success and the named reward terms of the reading ``s`` (the step's info)."""
        stage, progress, success = self.stage(s), self.progress(s), self.is_success(s)
        terms = self.reward_terms(s, stage, progress, success)
        if self.reward_mode == "shaped":
            terms.update(rewards.shaping(s, stage, progress))
        return {"stage": stage, "progress": float(progress), "success": bool(success),
                "object_name": s.obj.name, "sim_unstable": s.unstable, "reward_terms": terms}

    def _observe(self, s: State, info: dict) -> dict:
        r = s.robot
        vector = np.concatenate([r.qpos, r.palm_linvel, r.palm_angvel, r.palm_pos, self.extra_state(s),
                                 [s.t / s.horizon]])
        if self.observation == "state":  # no render at all
            info["point_labels"] = self._labels = np.zeros(0, np.int64)
            return {"state": np.concatenate([vector, self.privileged_state(s)]).astype(np.float32)}
        cloud = self.sensor.observe(self.np_random)
        info["point_labels"] = self._labels = cloud.labels
        obs = {"point_cloud": cloud.points, "imagined_mask": cloud.imagined.astype(np.int8),
               "state": vector.astype(np.float32)}
        if cloud.depth_image is not None:
            obs["depth_image"] = cloud.depth_image
        return obs

    def privileged_state(self, s: State) -> np.ndarray:
        """What the state-only diagnostic adds to the state vector: registration.STATE_ONLY_PRIVILEGED
        (``PRIVILEGED_STATE`` entries; the part's frame is its link's)."""
        pos, quat = self.sim.link_frames(self.objects.body, [PART_LINK])
        rot = pc.quat_to_matrix(quat[0])
        base = np.asarray(self.ROBOT_BASE, float)
        return privileged_vector(STATE_ONLY_PRIVILEGED, part_pos=pos[0] - base, part_rot=rot[:, :2].T, joint=s.q,
                                 joint_init=s.obj.joint_init, joint_target=s.obj.joint_target,
                                 grasp_pos=s.handle_pos - base)

    def _scenery_can_occlude(self, pose: CameraPose) -> bool:
        """Whether the table or the pedestal could hide a point of the crop box from this camera.

        Both lie outside the crop box (below zmin; behind xmin), so they never appear in the cloud.
        A segment from the camera to a point in the box stays above the table top (z = 0) when the
        camera is above it, and stays in front of the pedestal (x >= xmin in the robot frame) when
        the camera is; then the scenery cannot occlude anything and the depth camera may skip it
        (TinyRenderer's time follows what it draws). The perturbation of a few cm keeps this true.
        """
        position = np.asarray(pose.position, dtype=float)
        margin = 0.1  # m, covers the per-reset camera perturbation (1.5 cm std)
        above_table = position[2] > margin
        before_pedestal = self.PEDESTAL is None or position[0] - self.ROBOT_BASE[0] > self.CROP[0] + margin
        return not (above_table and before_pedestal)

    def _arm_links_out_of_view(self, margin: float = 0.1) -> list[tuple[int, tuple]]:
        """The arm's base and first link where they lie, at every joint angle, outside the box around
        the crop box and every eye position (eyes ``margin`` m wider, for the per-reset camera
        perturbation), with their colours.

        A point matters to the cloud only if it is in the crop box or between the eye and a point of
        it, i.e. inside the convex hull of the eye and the box, which this box contains; a link that
        never enters it changes no cropped point, so the depth camera need not draw it (TinyRenderer's
        time follows what it draws; ``tests/test_envs.py`` checks the clouds are identical). Bounds,
        from the collision boxes (``getAABB``; the visual hulls are made of collision-hull vertices,
        ``robot_model.simplified_arm_visual``, so they lie inside): the fixed base its box; link 1 the
        cylinder its box corners sweep about joint 1's axis. The links beyond swing too far to bound.
        """
        lo = np.minimum(np.add(self.ROBOT_BASE, self.CROP[0::2]), self._eyes.min(0) - margin)
        hi = np.maximum(np.add(self.ROBOT_BASE, self.CROP[1::2]), self._eyes.max(0) + margin)
        body = self.robot.body
        colour = self.sim.visual_colours(body)
        base, link1 = body.link(ARM_LINKS[0]), body.link(ARM_LINKS[1])
        boxes = {link: np.array(self.sim.aabb(body, link)) for link in (base, link1)}  # (2, 3) world, m
        corners = np.array([[x, y, z] for x in boxes[link1][:, 0] for y in boxes[link1][:, 1] for z in boxes[link1][:, 2]])
        (origin,), (quat,) = self.sim.link_frames(self.robot.body, [link1])  # joint 1's frame
        axis = pc.quat_to_matrix(quat) @ np.asarray(self.sim.joint_info(body, link1)[13])  # world, unit
        along = (corners - origin) @ axis  # (8,) heights along the axis
        radius = np.linalg.norm(corners - origin - along[:, None] * axis, axis=1).max()  # from the axis
        ends = origin + np.outer([along.min(), along.max()], axis)  # (2, 3) the cylinder's end centres
        sweep = radius * np.sqrt(np.clip(1.0 - axis**2, 0.0, None))  # (3,) half-extent of its end discs
        boxes[link1] = np.stack([ends.min(0) - sweep, ends.max(0) + sweep])
        return [(link, colour[link]) for link, box in boxes.items()
                if link in colour and (np.any(box[1] < lo) or np.any(box[0] > hi))]

    def _show_undrawn_links(self, visible: bool) -> None:
        for link, rgba in self._undrawn_links:
            self.sim.set_colour(self.robot.body, link, rgba if visible else (*rgba[:3], 0.0))

    def _show_scenery(self, visible: bool) -> None:
        self._scenery_hidden = not visible
        for body, rgba in zip(self.scenery, (TABLE_RGBA, PEDESTAL_RGBA)):
            self.sim.set_colour(body, BASE_LINK, rgba if visible else (0, 0, 0, 0))

    def _camera_pose(self, camera) -> CameraPose:
        if camera is None:
            return self.CAMERA
        if isinstance(camera, CameraPose):
            return camera
        if isinstance(camera, dict) and set(camera) == {"eye", "target"}:
            return CameraPose.look_at(camera["eye"], camera["target"])
        raise ValueError("camera must be a CameraPose or a dict {'eye': [x, y, z], 'target': [x, y, z]} (world, m)")
