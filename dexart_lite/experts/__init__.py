"""Scripted experts: one privileged-state controller per task, proof that every task is solvable and
the teachers of the distilled students.

They act through the same 22-D action as a learned policy (palm twist + hand joint targets) but
read the simulator directly: the functional part's pose, its joint angle and its geometry. Each is a
short state machine (or, for the laptop and the toilet, a state-feedback law) of palm poses defined in the functional
part's frame, tracked by a Cartesian controller (``controller.PalmController``). The manipulation
"rides" the part: it asks for the grasp pose of the part turned a little further than it is now, so
the hand pushes the part along its joint.

    policy = ScriptedPolicy(env)        # observation -> action, for any env of the four tasks
    dexart-lite solve --task laptop --split seen --episodes-per-object 3 --json laptop.json

Layout (mirrors ``dexart_lite.envs``): ``geometry`` (rotations, poses, finger reach, pure pursuit),
``controller`` (palm pose -> twist, hand shapes), ``base`` (the part's frame, the ``Solver`` base),
one module per task family (``lid``: the lid grasp's geometry and the phased lid expert; ``laptop``:
the feedback lid expert of laptops and toilets; ``faucet``, ``bucket``) and ``solve``
(success over a split, the CLI).
"""

from __future__ import annotations

import numpy as np

from dexart_lite.experts.base import PartFrame, Solver
from dexart_lite.registration import PRIVILEGED_DIM
from dexart_lite.experts.bucket import BucketSolver, OverhandBucketSolver
from dexart_lite.experts.faucet import FaucetSolver
from dexart_lite.experts.laptop import FeedbackLidSolver
from dexart_lite.registration import SPECS
from dexart_lite.robot import synergy_action
from dexart_lite.utils import check_choice

# Laptop and toilet: the state-feedback lid expert (imitable, see FeedbackLidSolver). The phase-machine
# LidSolver it builds on opened every toilet (1.00 / 1.00) but its students failed (0.08 / 0.03, 3 seeds):
# its decisions hinge on counters no observation shows and its side of approach flips with the placement.
# Each task's expert is named in its spec (registration.SPECS).
EXPERTS = {c.__name__: c for c in (BucketSolver, OverhandBucketSolver, FaucetSolver, FeedbackLidSolver)}
SOLVERS = {task: EXPERTS[spec.expert] for task, spec in SPECS.items()}
# The experts a task can run by name: its own, and earlier ones kept to be measured beside it (``solve(expert=...)``,
# ``benchmarks/experts/exploration_noise.py --expert``): the bucket's fingertip hook, replaced by the overhand cage.
EARLIER = {"bucket": (BucketSolver,)}
TASK_EXPERTS = {task: [c.__name__ for c in (SOLVERS[task], *EARLIER.get(task, ()))] for task in SPECS}


class ScriptedPolicy:
    """observation -> action for a DexArt-lite env, using the env's privileged state.

    ``expert``: the class name of another expert of the task than its own (``TASK_EXPERTS``).
    A new solver starts with every episode (step 0, or another object or pose than the last call's).
    ``privileged`` holds ``Solver.privileged`` of the state the last action answered.
    """

    def __init__(self, env, expert: str | None = None):
        self.env = env.unwrapped
        check_choice("task with a scripted solver", self.env.CATEGORY, SOLVERS)
        if expert is not None:
            check_choice(f"{self.env.CATEGORY} expert", expert, TASK_EXPERTS[self.env.CATEGORY])
        self.expert = SOLVERS[self.env.CATEGORY] if expert is None else EXPERTS[expert]  # the Solver class
        self.solver: Solver | None = None
        self._episode = None
        self.privileged: np.ndarray | None = None

    def __call__(self, obs=None) -> np.ndarray:
        env, state = self.env, self.env.state
        key = (id(state.obj), state.base_pos_at_reset.tobytes())
        if state.t == 0 or self.solver is None or key != self._episode:
            self.solver, self._episode = self.expert(env), key
        self.privileged = self.solver.privileged(state)  # of the state this action answers
        return np.clip(self.solver.act(state), -1.0, 1.0)


class SynergyScriptedPolicy(ScriptedPolicy):
    """The scripted expert for an env with ``hand="synergy"``: its twist, and its 16 hand joint targets
    projected on the 3 synergies (``robot.synergy_action``). How much of an expert survives the projection
    says whether the synergy hand can still do the task (``benchmarks/experts/synergy_expert.py``)."""

    def __call__(self, obs=None) -> np.ndarray:
        a = super().__call__(obs)  # (22,)
        return np.concatenate([a[:6], synergy_action(self.env.robot.hand_targets(a[6:]))])  # (9,)


__all__ = ["EXPERTS", "SOLVERS", "TASK_EXPERTS", "PRIVILEGED_DIM", "BucketSolver", "OverhandBucketSolver",
           "FaucetSolver", "FeedbackLidSolver", "PartFrame", "ScriptedPolicy", "Solver", "SynergyScriptedPolicy"]
