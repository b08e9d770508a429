"""The task names and specs, the episode length and the gymnasium ids, registered without importing the envs.

Registration uses string entry points, so ``import dexart_lite`` stays light (no PyBullet) and the
ids also exist in spawned worker processes, which re-import the package.

``SPECS`` holds every fact about a task that more than one module needs: where the robot stands, the
reset randomisation, the split sizes, the success thresholds, the expert, what a distilled student may
not see, the state vector's size. The env classes (``envs/<task>.py``), the object catalog
(``objects/``), the experts and the learners read them from here; ``tests/test_envs.py`` checks that
no other module writes these values down again. Facts used by one module only (reward weights, camera
poses, crop boxes) stay in that task's env file.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from dexart_lite.utils import check_choice


@dataclass(frozen=True)
class TaskSpec:
    name: str
    robot_base: tuple[float, float, float]  # m, world position of the arm's base (it faces +x); DexArt's
    rand_pos: float  # m, reset noise on the object's position, one-sided U[0, rand_pos) on x, y and z (DexArt)
    rand_yaw_deg: float  # degrees, reset noise on the object's yaw, U[-rand_yaw_deg, rand_yaw_deg] (DexArt)
    seen: int  # training objects (DexArt's split sizes)
    unseen: int  # test objects
    half: int  # the "seen_half" split: the first this many seen objects (DexArt's ablation)
    success: dict = field(default_factory=dict)  # the thresholds of ``is_success`` (names in the env file)
    expert: str = ""  # the scripted expert's class in ``dexart_lite.experts``
    student_drops: str = ""  # state entries a distilled student does not see by default (distill --drop-state auto)
    state_dim: int = 32  # entries of the state vector (the bucket adds its lift)


SPECS = {
    "faucet": TaskSpec("faucet", (-0.5, 0.0, 0.0), 0.1, 90.0, seen=11, unseen=7, half=5,
                       success={"angle": 1.5}, expert="FaucetSolver"),  # rad (~86 degrees) turned
    "bucket": TaskSpec("bucket", (-0.5, 0.0, 0.3), 0.05, 0.0, seen=11, unseen=8, half=5,
                       success={"progress": 0.7, "lift": 0.25}, expert="OverhandBucketSolver", state_dim=33),  # lift: m
    # laptop students that saw time and the palm's velocity learned to wait instead of to look
    # (docs/results/students.md)
    "laptop": TaskSpec("laptop", (-0.5, 0.0, 0.0), 0.1, 60.0, seen=11, unseen=6, half=5,
                       success={"progress": 0.95}, expert="FeedbackLidSolver", student_drops="time,palm_velocity"),
    "toilet": TaskSpec("toilet", (-0.5, 0.0, 0.4), 0.2, 45.0, seen=17, unseen=11, half=8,
                       success={"progress": 0.95}, expert="FeedbackLidSolver"),
}
TASKS = tuple(SPECS)
HORIZON = 250  # control steps per episode (10 s at 25 Hz): the registered max_episode_steps
OBSERVATIONS = ("cloud", "state")  # the env's ``observation``: DexArt's point cloud + state; the state-only diagnostic
HAND_MODES = ("joints", "synergy")  # the env's ``hand``: DexArt's 16 joint targets; 3 synergies (robot.py)
ENV_IDS = [f"DexArtLite/{task.capitalize()}-v0" for task in TASKS]

# The state vector of every task, in order (name -> entries): the 22 joint positions (arm, then hand; rad), the
# palm's linear (m/s) and angular (rad/s) velocity, the palm's position (m, world), the task's own entries
# (``TaskSpec.state_dim`` - 32 of them: the bucket's palm-up) and the time, t / horizon.
STATE_LAYOUT = {"qpos": 22, "palm_velocity": 6, "palm_pos": 3, "task": None, "time": 1}

# The privileged state, defined once: every entry a privileged vector may hold (name -> entries), in this order.
# part_pos: the functional part's link origin from the robot base (m); part_rot: the first two columns of its
# rotation matrix; joint, joint_init, joint_target: its joint angle now, at reset and for success (rad);
# part_bounds: its mesh's min and max corner in its own frame (m); grasp_pos: the grasp point from the robot base (m).
PRIVILEGED_ENTRIES = {"part_pos": 3, "part_rot": 6, "joint": 1, "joint_init": 1, "joint_target": 1,
                      "part_bounds": 6, "grasp_pos": 3}
STATE_ONLY_PRIVILEGED = ("part_pos", "part_rot", "joint", "joint_init", "joint_target", "grasp_pos")  # the
# state-only diagnostic's observation appends these (DexArtEnv.privileged_state)
EXPERT_PRIVILEGED = ("part_pos", "part_rot", "joint", "joint_target", "part_bounds", "grasp_pos")  # what a scripted
# expert knows and a distilled student must find in its cloud (Solver.privileged; distillation's auxiliary target)
PRIVILEGED_STATE = sum(PRIVILEGED_ENTRIES[n] for n in STATE_ONLY_PRIVILEGED)  # 15
PRIVILEGED_DIM = sum(PRIVILEGED_ENTRIES[n] for n in EXPERT_PRIVILEGED)  # 20


def state_slices(task: str) -> dict[str, slice]:
    """Where each entry of ``STATE_LAYOUT`` sits in ``task``'s state vector."""
    check_choice("task", task, TASKS)
    sizes = {**STATE_LAYOUT, "task": SPECS[task].state_dim - sum(v for v in STATE_LAYOUT.values() if v)}
    return _slices(sizes, sizes)


def privileged_slices(names: tuple[str, ...] = EXPERT_PRIVILEGED) -> dict[str, slice]:
    """Where each entry sits in a privileged vector made of ``names`` (by default, an expert's)."""
    return _slices(names, PRIVILEGED_ENTRIES)


def privileged_vector(names: tuple[str, ...], **values) -> np.ndarray:
    """The privileged vector of ``names``, in that order, from one value per name (float64; shapes checked)."""
    parts = []
    for name in names:
        part = np.ravel(np.asarray(values[name], float))
        if part.size != PRIVILEGED_ENTRIES[name]:
            raise ValueError(f"privileged entry {name!r} has {PRIVILEGED_ENTRIES[name]} values, got {part.size}")
        parts.append(part)
    return np.concatenate(parts)


def _slices(names, sizes: dict) -> dict[str, slice]:
    out, start = {}, 0
    for name in names:
        out[name] = slice(start, start + sizes[name])
        start += sizes[name]
    return out


def env_id(task: str) -> str:
    """The gymnasium id of ``task``; ``ValueError`` listing the tasks if unknown."""
    check_choice("task", task, TASKS)
    return f"DexArtLite/{task.capitalize()}-v0"


def register_all() -> None:
    for task, id_ in zip(TASKS, ENV_IDS):
        if id_ not in gym.registry:
            gym.register(id=id_, entry_point=f"dexart_lite.envs.{task}:{task.capitalize()}Env",
                         max_episode_steps=HORIZON)
