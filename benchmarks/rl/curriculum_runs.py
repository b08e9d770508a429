"""RL that starts from the experts: one recipe on one task and observation, several seeds, evaluated from the true reset.

    python benchmarks/rl/curriculum_runs.py --task laptop --obs state --recipe reverse_bc --seeds 0 1 --jobs 2 \
        --frames 1000000 --max-minutes 60
    python benchmarks/rl/curriculum_runs.py ...               # again: a seed short of --frames continues from its
                                                               # checkpoint, a finished one is read back
    python benchmarks/rl/curriculum_runs.py --task bucket --obs cloud --recipe student_anchored --seeds 0 \
        --students-only                                        # the point-cloud student step alone (no RL)

Each seed is one ``dexart_lite.rl.ppo.train`` run in ``runs/curriculum/<task>_<obs>_<recipe>_s<seed>``, trained,
continued or read back by ``dexart_lite.study.run_arm`` (the rule every multi-seed script shares; with
``--jobs 2`` two seeds train at once, one collector process each). Written, after every finished seed, to
``benchmarks/results/rl/curriculum/<task>_<obs>_<recipe>.json``:

    task, obs, recipe, settings (the PPOConfig fields the recipe sets), frames (online env frames per seed,
    the guide's steps excluded), demo_frames (the demonstrations' steps, counted apart), per_seed (seed,
    frames, seen_success, unseen_success, wall_time_s (training, summed over the run's invocations),
    wall_time_with_eval_s (this invocation alone, its evaluation included), demo_frames, guide_success, curve:
    frames, success of the collected episodes, of those from the true reset (h = 0) and from the frontier, the
    mean frontier),
    seen_success / unseen_success (means over the seeds), eval_episodes_per_object, command, machine.

Runs that span several sittings: at the end of every call each seed stopped short of ``--frames`` (``--max-minutes``)
is parked in ``benchmarks/results/in_progress/<run>`` (``--committed``): its last checkpoint, ``run.json`` and the
held-out evaluations of that checkpoint (``heldout_*.json``), and its student's, nothing else (no logs, no
demonstrations), to be committed; a finished seed's folder there is deleted. A parked run whose folder ``--runs``
lacks is copied there first, and so continued (``--no-committed``: never read from or written to that folder).

``--students-only`` (student recipes) distils the students alone and writes ``<task>_cloud_student.json`` (a recipe
from a student variant: ``<task>_cloud_student_<variant>.json``, ``STUDENT_VARIANTS``): task,
student (the DistillConfig), per_seed (seed, frames, wall_time_s, checkpoint, seen_success, unseen_success),
seen_success / unseen_success (means), eval_episodes_per_object, eval_seed, command, machine.

Evaluation: deterministic actions from the true reset (no guide), ``--eval-episodes`` per seen and unseen
object, env seed 100, as ``dexart-lite eval``. The guide and the demonstrations are the scripted experts,
which read the simulator: they are used in training only; the policy observes what it always does.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import sys
from pathlib import Path

import torch

from dexart_lite.objects import list_objects
from dexart_lite.imitation.distill import CHECKPOINT, DistillConfig
from dexart_lite.rl import ppo, recipes
from dexart_lite.rl.evaluate import heldout_current
from dexart_lite.rl.learners import LEARNERS, learner_name
from dexart_lite.study import run_arm
from dexart_lite.cli import add_config_arguments
from dexart_lite.utils import benchmark_results, fast_mode, machine_info, provenance, sibling_script, write_json

RESULTS = benchmark_results(__file__) / "curriculum"
harness = sibling_script(__file__, "_harness")
# the one folder for runs that span several sittings: only their latest checkpoints, deleted when they finish
IN_PROGRESS = benchmark_results(__file__).parent / "in_progress"
# Recipes: the fast preset (4k frames per batch, 5 epochs, lr 3e-4, rewards x 0.01) plus these fields.
# reverse_bc: RFCL's reverse curriculum (a frontier per demonstration, moved back 5 steps after 3 successes in
# a row from it) on a policy cloned from the expert first (30 epochs of MSE on 4 noisy expert episodes per
# training object, inputs normalised with their statistics), whose critic learns alone for 3 batches, with a
# BC term (weight 0.5, x 0.95 per batch) and a small action std (0.1): the warm start keeps the grasp the
# expert made at the hand-over, the curriculum walks the start back to the true reset.
DEMO = {"demo_episodes": 4, "demo_noise": 0.1, "bc_warmstart": 30, "critic_warmup": 3, "bc_coef": 0.5,
        "bc_decay": 0.95, "init_log_std": -2.3, "obs_norm_steps": 0}
# guarded: the warm start kept through PPO's first updates, the guards the finetune preset measured on
# distilled students: the value loss stays out of the shared trunk (critic_detach) with its own lr 1e-3, the
# actor's lr 1e-4 (not 3e-4) with SB3's KL early stop at 0.02; a stronger, slower-decaying BC term (1.0, x 0.99
# per batch) on twice the demonstrations (8 per object), cloned for 50 epochs, and 5 critic-only batches.
WIDE = {"head": "256,256", "state_hidden": 256}
GUARDED = {**DEMO, "demo_episodes": 8, "bc_warmstart": 50, "critic_warmup": 5, "bc_coef": 1.0, "bc_decay": 0.99,
           "critic_detach": True, "critic_lr": 1e-3, "lr": 1e-4, "target_kl": 0.02}
# anchored: the `finetune` preset of rl/ppo_config.py (lr 3e-5, KL stop 0.01, 5 critic-only batches, critic kept out
# of the trunk) with a KL penalty to the student (anchor_coef 1), the setting that raised earlier laptop students on
# both splits (benchmarks/results/rl/finetune_laptop_anchor.json), from the headline student, no BC term
ANCHORED = {**{k: v for k, v in recipes.ANCHORED.items() if k != "eval_episodes"}, "student": True}
RECIPES = {
    "ppo": {},
    "bc": dict(DEMO),  # the same warm start and BC term, every episode from the true reset
    "reverse_bc": {**DEMO, "curriculum": "reverse", "curriculum_demos": 11, "curriculum_step": 5},
    # dagger: the guarded recipe from a better-cloned policy: after the BC warm start, 3 DAgger rounds in which
    # the cloned policy drives 4 episodes per object and the expert labels what it visits (their steps count
    # as demonstration frames, not online frames)
    "reverse_dagger": {**GUARDED, "demo_episodes": 4, "dagger_rounds": 3, "curriculum": "reverse",
                       "curriculum_demos": 11, "curriculum_step": 5},
    "reverse_guarded": {**GUARDED, "curriculum": "reverse", "curriculum_demos": 11, "curriculum_step": 5},
    # wide: the dagger recipe on a 256-unit state MLP and 256x256 heads (DexArt's actor is 64 / 64x64): the
    # clone it starts from opens 0.55 / 0.56 of the laptops instead of 0.05 / 0.08
    # (benchmarks/results/rl/curriculum/clone_capacity_laptop_state.json)
    "dagger_wide": {**GUARDED, "demo_episodes": 4, "dagger_rounds": 3, **WIDE},
    # the off-policy learner (rl/sac.py, SACConfig's defaults: 4 noisy expert episodes per object in a buffer of
    # their own, half of every batch; 2 LayerNorm critics; 1 update per frame after 5,000 frames; a 256-unit
    # state trunk and one 256-unit hidden layer in each network)
    # point clouds: PPO from the task's distilled DAgger student (the `student` step: `distill` with the
    # settings of the student in the README's headline table, STUDENTS) with the guards above; nothing is
    # cloned again: the guide's 4 noisy episodes per object and 3 rounds of 4 episodes per object that the
    # student drives (labelled by the guide) are the BC term's data
    "student_guarded": {**GUARDED, "demo_episodes": 4, "dagger_rounds": 3, "bc_warmstart": 0, "student": True},
    "student_anchored": dict(ANCHORED),  # ANCHORED above
    # anchored_release: the anchor let go within a short run (x 0.95 per batch: half its weight ~14 batches, 56k
    # frames, after the critic warm-up, a tenth after ~45): does PPO climb above the student or fall from it
    # once the KL to it no longer holds it?
    "student_anchored_release": {**ANCHORED, "anchor_decay": 0.95},
    "sac_demos": {"algo": "sac"},
    "sac_reverse": {"algo": "sac", "curriculum": "reverse", "curriculum_demos": 11, "curriculum_step": 5},
}
# <recipe>_capped: the recipe on reward="capped" (envs/rewards.py; not DexArt's), nothing else changed: the terminal
# bonus stops counting at the success threshold, so a success is not worth more for flinging the handle further; on
# the faucet, DexArt's bonus lets PPO trade reliability for bigger, earlier successes at equal return
# (benchmarks/results/rl/return_vs_success_faucet.json), and once an anchor is let go nothing else holds it back.
# <recipe>_flat: the recipe on reward="flat" (not DexArt's), nothing else changed: a success pays the same fixed
# bonus at any step, so the return ranks reliability first; capped, PPO still trades reliability for speed
# (benchmarks/results/rl/return_vs_success_faucet_capped.json)
for _name in ("dagger_wide", "student_anchored_release"):
    RECIPES[f"{_name}_capped"] = {**RECIPES[_name], "reward": "capped"}
    RECIPES[f"{_name}_flat"] = {**RECIPES[_name], "reward": "flat"}
# student_anchored_floor_flat: student_anchored_release_flat with the anchor's decay stopped at a tenth of its start
# (anchor_floor 0.1, reached after ~45 batches, ~180k frames past the warm-up). Let go entirely, the faucet policies
# were within noise of their students at ~440k frames (held out; one seed above, one below) and below both at ~580k,
# while the KL to the student grew from 0.6 to 1.3 nats per step; the constant anchor (weight 1) held
# the students at KL ~0.02 and added nothing. Does a weaker anchor that is never let go stop the drift?
RECIPES["student_anchored_floor_flat"] = {**RECIPES["student_anchored_release_flat"], "anchor_floor": 0.1}
# student_anchored_floor_flat_b16k: the same against the gradient noise: 4x the frames per update (16,000: ~90 faucet
# episodes, ~8 per seen faucet, instead of ~22) and 4x the samples per gradient step (minibatch 2,000), with the same
# trust region per update (KL stop 0.01) and the anchor's schedule unchanged per frame (x 0.95^4 per batch; critic
# warm-up 2 batches, 32k frames, instead of 5 x 4k). Adam's step size does not shrink with a noisier gradient, and
# the 4k updates stop at the KL limit after 4-10 steps of 500 samples, so each moves the policy by as much whatever
# it learnt; held-out checkpoints of one run swing by up to 0.2. Per frame the policy moves ~4x less,
# each step on a 4x less noisy gradient (docs/results/rl_from_experts.md)
BIG_BATCH = recipes.BIG_BATCH
RECIPES["student_anchored_floor_flat_b16k"] = {**RECIPES["student_anchored_floor_flat"], **BIG_BATCH}
# student_anchored_floor: the same floor on DexArt's own reward, for toilets: there the flat bonus took the students
# down as the anchor let go, while on DexArt's reward the released anchor gained a little
RECIPES["student_anchored_floor"] = {**RECIPES["student_anchored_release"], "anchor_floor": 0.1}
# <recipe>_b16k on the other tasks: BIG_BATCH alone added to each task's own best point-cloud recipe, so that the
# comparison with it isolates the batch size (laptop: the released anchor on the flat bonus;
# toilet: the floor on DexArt's reward)
RECIPES["student_anchored_release_flat_b16k"] = {**RECIPES["student_anchored_release_flat"], **BIG_BATCH}
RECIPES["student_anchored_floor_b16k"] = {**RECIPES["student_anchored_floor"], **BIG_BATCH}
# student_anchored_floor_reverse: the same from the experts' states, for buckets, whose students never lift a bucket
# from the true reset (so PPO from the reset collects no success to learn from): RFCL's reverse curriculum on 11
# (seed, object) pairs the scripted expert solves, each start frontier first one step before its first success
# and moved back 5 steps after 3 successes in a row from it; 10 % of the episodes from the true reset
RECIPES["student_anchored_floor_reverse"] = {**RECIPES["student_anchored_floor"], "curriculum": "reverse",
                                             "curriculum_demos": 11, "curriculum_step": 5}
# student_anchored_floor_reverse_eager: the same with the frontier moved back after ONE success from it (Salimans & Chen
# move theirs once 20 % of the rollouts from it succeed). RFCL's 3 in a row suits SAC's high success from the frontier;
# at PPO's 0.2-0.5 from the bucket frontier 3 in a row needs ~10-25 tries, and the frontier stalled near 140
RECIPES["student_anchored_floor_reverse_eager"] = {**RECIPES["student_anchored_floor_reverse"],
                                                   "curriculum_successes": 1}
# student_anchored_floor_reverse_std03: the same with an exploration std of 0.03 instead of 0.1 (log std -3.5). The
# expert itself, handed its own episode after h steps and acting with executed-action noise of std 0.1, lifts 0.00-0.09
# of the buckets from h <= 100 and 0.73 from h = 125-140 (benchmarks/results/rl/bucket_expert_noise_from_h.json): the
# raise does not survive std-0.1 exploration, whoever's mean it is, and the std-0.1 frontier stopped at ~130. At std
# 0.03 the expert lifts 0.64 from the reset and 0.91 from h = 100. Between Gaussians of one std the KL is
# sum((delta mu)^2) / (2 std^2), so the anchor's weight and floor are multiplied by (0.03 / 0.1)^2 and the KL early stop
# divided by it: they hold the policy's mean actions as near to the student, and let them move as far per batch, as at
# std 0.1 (PPO's ratio clip, 0.2, is unchanged and so binds sooner in action units)


at_std = recipes.at_std  # the anchor and the KL stop rescaled to another exploration std


RECIPES["student_anchored_floor_reverse_std03"] = at_std(RECIPES["student_anchored_floor_reverse"], 0.03)
# student_anchored_floor_flat_b16k_std03: the laptop's recipe at exploration std 0.03, for buckets: from the
# overhand expert's students (0.44 / 0.33 deterministic) the std-0.1 collections lift ~0.05 of the buckets, so PPO
# would see almost no success; at std 0.03 the anchor's weight and floor and the KL stop are rescaled (at_std)
RECIPES["student_anchored_floor_flat_b16k_std03"] = at_std(RECIPES["student_anchored_floor_flat_b16k"], 0.03)
# student_anchored_floor_reverse_std03_backoff: the same with a frontier that also moves forward 5 steps after 6
# failures in a row from it (Florensa et al. keep starts at 0.1-0.9 success; RFCL only moves back). At std 0.03 the
# collected success fell from 0.6 to 0.2 within 150k frames and nothing brought it back; 3 successes
# in a row back, 6 failures forward move it equally often where success from the frontier is ~0.35. Run:
# collected success 0.35-0.45 instead of 0.2-0.3, held out 0.11 / 0.06, level with std03's 0.10 / 0.05
RECIPES["student_anchored_floor_reverse_std03_backoff"] = {**RECIPES["student_anchored_floor_reverse_std03"],
                                                            "curriculum_backoff": 6}
# student_anchored_floor_reverse_d17: the reverse curriculum on toilets, one demonstration per seen toilet (17; the
# bucket recipes' 11 would leave 6 toilets without guided starts). Unlike the bucket expert, the toilet expert keeps
# 0.91-1.00 from every h at std 0.1 (benchmarks/results/rl/toilet_expert_noise_from_h.json), so it keeps std 0.1
RECIPES["student_anchored_floor_reverse_d17"] = {**RECIPES["student_anchored_floor_reverse"], "curriculum_demos": 17}
# dagger_wide_flat_g999: dagger_wide_flat with gamma 0.999 (DexArt and the presets: 0.99). A success bonus B at step t
# is worth gamma^t * B from the reset, so at 0.99 a policy that succeeds 0.8 of the time at step 100 (0.29 B) still
# outranks one that succeeds 0.98 of the time at step 132 (0.26 B) whatever the bonus; at 0.999 (0.72 B against
# 0.86 B) reliability ranks first
RECIPES["dagger_wide_flat_g999"] = {**RECIPES["dagger_wide_flat"], "gamma": 0.999}
# dagger8_wide_flat: dagger_wide_flat from a better clone: 8 DAgger rounds instead of 3 (the clone alone turns
# 0.91 / 0.89 of the faucets instead of ~0.79 / 0.75:
# benchmarks/results/rl/curriculum/clone_capacity_faucet_state_rounds8.json). On the capped and flat rewards PPO at
# best holds the clone it starts from (it ends ~0.06 below this one), so the clone sets the level
RECIPES["dagger8_wide_flat"] = {**RECIPES["dagger_wide_flat"], "dagger_rounds": 8}
# dagger8_wide: the same 8-round clone on DexArt's own reward (the faithful setting; dagger8_wide_flat is the named
# departure): does the better clone need the flat reward to keep >= 0.8 seen?
RECIPES["dagger8_wide"] = {**RECIPES["dagger_wide"], "dagger_rounds": 8}
# the committed JSON of each task's headline student (bench_distill): its "overrides" are the student step's
STUDENTS = {"faucet": "distill_faucet_episodes2x.json", "bucket": "distill_bucket_overhand.json",
            "laptop": "distill_laptop_episodes2x_noise.json", "toilet": "distill_toilet_episodes2x.json"}
# Student variants: a student recipe whose "student" is a name here starts from the headline student's settings plus
# these DistillConfig fields, distilled into runs/curriculum/<task>_cloud_student_<name>_s<seed> (True: the headline
# student itself, <task>_cloud_student_s<seed>).
# erase: random occlusion of the training clouds (distill's point_erase: half the samples lose the points within a
# ball of radius U[0.05, 0.2] m around one of theirs). Every seen toilet has a tank and the toilet policies find the
# lid by it (benchmarks/results/students/tank_ablation_toilet.json); the held-out template C has none. Chosen after
# looking at the unseen toilets, so for this variant the unseen split is no longer a blind test.
# rounds10: 10 DAgger rounds instead of 6 (beta 0.5 x 0.6^r, so rounds 7-10 run the student at 0.02-0.005 expert
# share: its own states, the expert's labels). The toilet students' round 6 opens about half the toilets it collects
# on (0.51 and 0.57: runs/curriculum/toilet_cloud_student_s*/log.csv); on the faucet's state clones 8 rounds instead
# of 3 lifted 0.80 -> 0.91 seen (clone_capacity_faucet_state_rounds8.json)
# betafloor: beta never below 0.2 (rounds 3-6 at 0.2 instead of 0.18, 0.11, 0.06, 0.04): the expert keeps driving a
# fifth of the steps, where the toilet students' collections still open ~0.9 of the toilets (rounds10: they fall
# once beta < 0.1, and the students with more low-beta rounds are worse)
# successonly: only the DAgger rounds' successful episodes join the buffer (drop_failed), so the states of failed
# episodes, which fill the low-beta rounds, are not fitted
# thumbfirst: no setting changed; the bucket students distilled from the overhand expert after its lift closed the
# thumb first (distill_bucket_thumbfirst.json), in folders of their own, apart from the students of the expert before
# wide: successonly on the 17 seen toilets plus the 17 of the wide split (templates A / B drawn beyond their seen
# ranges: outlines up to superellipse exponent 3, 6 of them tankless; dexart_lite/objects/toilet.py widen) with the same
# number of episodes: 5 demonstrations and 2 DAgger episodes per object and round over 34 toilets (9 and 4 over 17).
# The widening was chosen knowing that the held-out template C is squarish (exponent 3.5-5) and tankless
# wide2x: wide with the toilets' headline episodes per object (9 demonstrations and 4 DAgger episodes per toilet and
# round over 34 toilets, twice wide's): wide kept C at 0.26 but lost 0.05 seen with about half the episodes per seen
# toilet, and twice the episodes lifted the bucket students 0.43 -> 0.79 seen
# thumbfirst_successonly2x: the toilets' student recipe (twice the demonstrations and DAgger episodes per object, only
# the successful DAgger episodes kept) for the buckets: the overhand expert does not recover from perturbed states
# (0.00 at std 0.3), so its labels in the states of failed episodes lead nowhere, and its last rounds' collections
# lift 0.45-0.68 of the buckets
STUDENT_VARIANTS = {"erase": {"point_erase": 0.5, "point_erase_radius": 0.2}, "rounds10": {"rounds": 10},
                    "betafloor": {"beta_min": 0.2}, "successonly": {"drop_failed": True}, "thumbfirst": {},
                    "wide": {"drop_failed": True, "split": "seen_wide", "demo_episodes_per_object": 5,
                             "episodes_per_round": 2},
                    "wide2x": {**recipes.TWICE_THE_EPISODES, "drop_failed": True, "split": "seen_wide"},
                    "thumbfirst_successonly2x": {**recipes.TWICE_THE_EPISODES, "drop_failed": True}}
# student_erase_anchored_floor: student_anchored_floor (toilets' recipe on DexArt's reward) from the erase students
RECIPES["student_erase_anchored_floor"] = {**RECIPES["student_anchored_floor"], "student": "erase"}
# student_rounds10_anchored_floor_reverse_d17: the toilets' reverse-curriculum recipe from the rounds10 students
RECIPES["student_rounds10_anchored_floor_reverse_d17"] = {**RECIPES["student_anchored_floor_reverse_d17"],
                                                         "student": "rounds10"}
# ... and from the successonly students
RECIPES["student_successonly_anchored_floor_reverse_d17"] = {**RECIPES["student_anchored_floor_reverse_d17"],
                                                             "student": "successonly"}
# student_thumbfirst_anchored_floor_flat_b16k_std03: the bucket's RL recipe from the thumb-first expert's students
RECIPES["student_thumbfirst_anchored_floor_flat_b16k_std03"] = {**RECIPES["student_anchored_floor_flat_b16k_std03"],
                                                                "student": "thumbfirst"}
# ... and from the students of the toilets' student recipe (thumbfirst_successonly2x)
RECIPES["student_thumbfirst_successonly2x_anchored_floor_flat_b16k_std03"] = {
    **RECIPES["student_anchored_floor_flat_b16k_std03"], "student": "thumbfirst_successonly2x"}
# student_successonly_anchored_release: the toilets' headline RL recipe (student_anchored_release, 38 min per seed)
# from the successonly students, RL's gain over the better students on the same budget
RECIPES["student_successonly_anchored_release"] = {**RECIPES["student_anchored_release"], "student": "successonly"}
# student_successonly_anchored_release_std05: the same with an exploration std of 0.05 instead of 0.1. From these
# students the std-0.1 collections open ~0.5 of the toilets against 0.67 deterministic, and the released anchor lost
# -0.10 / -0.07 held out: PPO improved the noisy policy, not the deterministic one. The anchor's weight
# is multiplied by (0.05 / 0.1)^2 and the KL early stop divided by it, as for std03 above
RECIPES["student_successonly_anchored_release_std05"] = at_std(RECIPES["student_successonly_anchored_release"], 0.05)
# student_successonly_anchored_floor_reverse_d17_std05: from the same students, the toilet recipe that gained most
# from the older students (the reverse curriculum over one demonstration per seen toilet with the anchor's floor,
# +0.12 / +0.05 at 864k frames) at exploration std 0.05, where the released anchor held seen toilets
#; the floor keeps a tenth of the anchor's weight instead of letting it go
RECIPES["student_successonly_anchored_floor_reverse_d17_std05"] = at_std(
    RECIPES["student_successonly_anchored_floor_reverse_d17"], 0.05)
# student_wide_anchored_floor_reverse_d34_std05: the toilets' recipe above from the wide students, with PPO on the
# same training toilets as they (seen + wide) and one reverse-curriculum demonstration per training toilet
RECIPES["student_wide_anchored_floor_reverse_d34_std05"] = {
    **RECIPES["student_successonly_anchored_floor_reverse_d17_std05"], "student": "wide", "split": "seen_wide",
    "curriculum_demos": 34}
# ... and from the wide2x students
RECIPES["student_wide2x_anchored_floor_reverse_d34_std05"] = {
    **RECIPES["student_wide_anchored_floor_reverse_d34_std05"], "student": "wide2x"}
# student_wide_anchored_floor_reverse_d17_std05: the wide students with PPO on the 17 seen toilets alone (the successonly
# recipe's split and one reverse-curriculum demonstration per seen toilet). The wide students open 0.26 of template C
# but 0.59 of the seen toilets against successonly's 0.64, and PPO on seen + wide lost seen toilets further (0.54 at
# ~818k): here every RL frame goes to a seen toilet, while the anchor's floor keeps the policy near the student
RECIPES["student_wide_anchored_floor_reverse_d17_std05"] = {
    **RECIPES["student_successonly_anchored_floor_reverse_d17_std05"], "student": "wide"}
# the faucets' and laptops' headline point-cloud recipes from successonly students: their DAgger collections succeed
# 0.68-0.89 in the last rounds (toilets: 0.51-0.74, where the filter lifted the students from 0.47 / 0.30 to
# 0.68 / 0.31). Measured on faucets (`--students-only`): 0.65 / 0.64 held out against 0.70 / 0.64 without the filter,
# within the seeds' spread (docs/results/students.md), so their PPO was not run; the laptop recipe is defined, not run
RECIPES["student_successonly_anchored_floor_flat_b16k"] = {**RECIPES["student_anchored_floor_flat_b16k"],
                                                           "student": "successonly"}
RECIPES["student_successonly_anchored_release_flat"] = {**RECIPES["student_anchored_release_flat"],
                                                        "student": "successonly"}
# per batch: the collected episodes' success (all, from the true reset, from the frontier), the curriculum, the share of
# steps in each stage (where a failing learner stops), the critic's error at the episodes' first step, how much of
# the planned update the KL stop let through, the BC term's weight; the episodes' mean return (unscaled, on the run's
# own reward) and length
CURVE_KEYS = ("frames", "success_rate", "episode_return", "episode_length", "success_h0", "success_frontier",
              "frontier_mean", "start_mean", "stage1_frac", "stage2_frac", "stage3_frac", "value_error_h0", "value_error_guided",
              "update_steps_frac", "bc_weight", "anchor_weight", "kl_init", "wall_s")


def student_name(recipe: str) -> str:
    """The student a student recipe starts from: ``student`` (the headline one) or ``student_<variant>``."""
    variant = RECIPES[recipe].get("student")
    return "student" if variant is True else f"student_{variant}"


def student_config(task: str, seed: int, args, recipe: str) -> DistillConfig:
    """The distillation of ``recipe``'s ``student`` step: the headline student's settings plus its variant's
    (``STUDENT_VARIANTS``), this seed."""
    variant = RECIPES[recipe]["student"]
    overrides = json.loads((RESULTS.parents[1] / "students" / STUDENTS[task]).read_text())["overrides"]
    overrides.update(STUDENT_VARIANTS[variant] if variant is not True else {})
    overrides.update(task=task, seed=seed, eval_episodes=args.eval_episodes, progress=False,
                     threads=1 if args.jobs > 1 else 0,
                     out=str(Path(args.runs) / f"{task}_cloud_{student_name(recipe)}_s{seed}"))
    if fast_mode():  # as bench_distill's smoke run
        overrides.update(num_points=64, max_episode_steps=10, demo_episodes_per_object=1, rounds=1,
                         episodes_per_round=1, epochs=1, epochs_per_round=1, eval_episodes=1,
                         objects=list_objects(task, "seen")[0].name)
    return DistillConfig(**overrides)


def config(task: str, obs: str, recipe: str, seed: int, frames: int, args):
    """The run of one seed: the fast preset's ``PPOConfig`` plus the recipe's fields, or the config of the recipe's
    ``algo`` (its own defaults)."""
    overrides = dict(RECIPES[recipe], task=task, obs=obs, seed=seed, frames=frames,
                     eval_episodes=args.eval_episodes, max_minutes=args.max_minutes, progress=False,
                     threads=1 if args.jobs > 1 else 0, out=str(Path(args.runs) / f"{task}_{obs}_{recipe}_s{seed}"))
    if overrides.pop("student", False):
        if obs != "cloud":
            raise ValueError(f"recipe {recipe} starts from a point-cloud student: needs --obs cloud")
        overrides["init_from"] = str(Path(student_config(task, seed, args, recipe).out) / CHECKPOINT)
    algo = overrides.pop("algo", "ppo")
    if algo == "sac":
        if fast_mode():
            overrides.update(frames=200, frames_per_batch=100, warmup_frames=100, batch=32, demo_episodes=1, utd=0.25,
                             max_episode_steps=30, eval_episodes=1, num_points=64, curriculum_demos=2, buffer=1000)
        return LEARNERS[algo].config(**overrides)
    overrides["workers"] = args.workers
    overrides["device"] = args.device
    if fast_mode():  # a smoke run of the script itself, not evidence
        overrides.update(frames_per_batch=200, minibatch=100, epochs=1, num_points=64, max_episode_steps=30,
                         eval_episodes=1, frames=400, demo_episodes=min(overrides.get("demo_episodes", 0), 1),
                         bc_warmstart=min(overrides.get("bc_warmstart", 0), 2), curriculum_demos=2,
                         dagger_rounds=min(overrides.get("dagger_rounds", 0), 1))
        if overrides.get("curriculum", "none") != "none":  # the guide replays ~140 steps per guided start: 3 in 4
            overrides.update(curriculum_true_resets=0.75)     # episodes from the true reset keep the smoke run short
    return ppo.preset("fast", **overrides)


def no_nan(value):
    """JSON has no NaN: a statistic of no episode (NaN in the log) is written as null."""
    return None if isinstance(value, float) and math.isnan(value) else value


def training_seconds(history: list[dict]) -> float:
    """Training wall time over every invocation of a run: ``wall_s`` restarts at each ``--resume``."""
    ends = [a["wall_s"] for a, b in zip(history, history[1:]) if b["wall_s"] < a["wall_s"]]
    return sum(ends) + (history[-1]["wall_s"] if history else 0.0)


def run_seed(job: tuple) -> dict:
    """Distil the student first (``student`` recipes, once), then train, continue or read back one seed, both
    through the one multi-seed runner (``study.run_arm``); its row of ``per_seed``."""
    cfg, student = job
    if student is not None:
        run_arm(student)
    record = run_arm(cfg)
    demos = record["demos"] or {}
    return {"seed": cfg.seed, "frames": record["frames"],
            "seen_success": record["seen_success"], "unseen_success": record["unseen_success"],
            "seen_mean_max_stage": record["mean_max_stage"]["seen"],
            "unseen_mean_max_stage": record["mean_max_stage"]["unseen"],
            "wall_time_s": round(training_seconds(record["history"]), 1),
            "wall_time_with_eval_s": round(record["wall_time_s"], 1), "resumed": record["continued"],
            "trained_in_this_call": not record["resumed"],  # False: read back from its run.json
            "demo_frames": demos.get("frames", 0), "guide_success": demos.get("guide_success"),
            "dagger_success": demos.get("dagger_success"),
            # the cloned policy before any PPO update (a continued run reads it from its checkpoint)
            "warmstart_success": demos.get("warmstart_eval"),
            "student_success": student_success(student),
            "curve": curve(record["history"])}


def student_success(student: DistillConfig | None) -> dict | None:
    """The distilled student's own evaluation (``distill`` writes it: same episodes per object and env seed as the
    PPO run's), the success RL starts from; None without a student."""
    if student is None:
        return None
    return {split: json.loads((Path(student.out) / f"eval_{split}.json").read_text())["success_rate"]
            for split in ("seen", "unseen")}


def distil_students(students: list[DistillConfig], path: Path, argv, note: str | None, jobs: int = 1) -> dict:
    """``--students-only``: the ``student`` step alone, each seed distilled (or read back when its report exists;
    ``jobs`` seeds at a time, one process each), written to ``path`` as each seed ends: the distillation settings,
    per seed its frames, wall time and success, the means."""
    summary = {"task": students[0].task, "obs": "cloud", "step": "student",
               "student": dataclasses.asdict(students[0]) | {"seed": None, "out": None},
               "eval_episodes_per_object": students[0].eval_episodes, "eval_seed": students[0].eval_seed,
               "per_seed": [], **provenance(__file__, argv),
               "machine": {**machine_info(), "torch_threads": torch.get_num_threads()},
               **({"note": note} if note else {})}
    for student, _ in zip(students, harness.each(run_arm, [{"cfg": cfg} for cfg in students], jobs=jobs,
                                                 desc="students")):
        add_student(summary, student, path)
    return summary


def add_student(summary: dict, student: DistillConfig, path: Path) -> None:
    """One finished student's row in ``summary`` (and the means), written to ``path``."""
    from dexart_lite.rl.checkpoint import load_checkpoint

    with (Path(student.out) / "log.csv").open(newline="") as f:
        wall = float(list(csv.DictReader(f))[-1]["wall_s"])  # the last round's training time
    checkpoint = Path(student.out) / CHECKPOINT
    summary["per_seed"].append({"seed": student.seed, "frames": load_checkpoint(checkpoint)["frames"],
                                "wall_time_s": round(wall, 1), "checkpoint": str(checkpoint),
                                **{f"{k}_success": v for k, v in student_success(student).items()}})
    for key in ("seen_success", "unseen_success"):
        summary[key] = sum(r[key] for r in summary["per_seed"]) / len(summary["per_seed"])
    write_json(path, summary)


def curve(history: list[dict]) -> list[dict]:
    return [{k: no_nan(row.get(k)) for k in CURVE_KEYS} for row in history]


def refresh_curves(path: Path, runs: Path, note: str | None = None) -> dict:
    """Rewrite the ``curve`` of every seed of a written JSON from its run's checkpoint (``CURVE_KEYS`` as they are
    now), and its ``note`` if one is given; nothing is trained or evaluated again."""
    from dexart_lite.rl.checkpoint import load_checkpoint

    summary = json.loads(path.read_text())
    if note:
        summary["note"] = note
    for row in summary["per_seed"]:
        run = runs / f"{summary['task']}_{summary['obs']}_{summary['recipe']}_s{row['seed']}"
        history = load_checkpoint(run / ppo.CHECKPOINT)["history"]
        if history[-1]["frames"] != row["frames"]:
            raise ValueError(f"{run} holds {history[-1]['frames']} frames, the JSON {row['frames']}")
        row["curve"] = curve(history)
    write_json(path, summary)
    return summary


def machine_records(machine: dict, earlier: dict | None, rows: list[dict]) -> dict:
    """``machine`` and ``earlier_machines`` of the JSON: where the runs in ``rows`` trained. ``earlier`` is the JSON
    this call replaces (None: none). A run continued in this call keeps the earlier JSON's machines before this one
    (``earlier_machines``, oldest first); where every seed was read back, the earlier JSON's records stand."""
    trained = [r for r in rows if r["trained_in_this_call"]]
    if earlier is not None and not trained:
        return {k: earlier[k] for k in ("machine", "earlier_machines") if k in earlier}
    if earlier is not None and any(r["resumed"] for r in trained):
        return {"machine": machine, "earlier_machines": [*earlier.get("earlier_machines", []), earlier["machine"]]}
    return {"machine": machine}


def adopt_committed(out: Path, committed: Path) -> bool:
    """Copy the parked run of ``out``'s name (``committed/<name>``: an unfinished run's last checkpoint, or the
    student it starts from) into ``out`` when ``out`` does not exist, so that it is continued or read back
    (``run_arm`` still compares its settings) instead of done again: a student takes ~45 min per seed to distil
    on two cores. True if one was copied."""
    import shutil

    source = committed / out.name
    if out.exists() or not (source / "run.json").exists():
        return False
    shutil.copytree(source, out)
    print(f"{out.name}: copied the parked run from {source}; it is continued or read back")
    return True


# what a parked run keeps: enough to continue (PPO, SAC) or to be read back (a student), nothing that can be made again
# cheaply; ``park`` adds the checkpoint's own held-out evaluations (heldout_*.json)
PARKED_FILES = ("run.json", "checkpoint.pt", "eval_seen.json", "eval_unseen.json", "report.md")


def park(cfgs: list, students: list, committed: Path) -> list[str]:
    """After a call: each run of ``cfgs`` stopped short of its frames is copied (``PARKED_FILES`` only) with its
    student to ``committed/<name>``; a finished run's folder there is deleted, and so is a student's that no parked
    run starts from any more. The names parked now, sorted."""
    import shutil

    def copy(folder: Path) -> None:
        target = committed / folder.name
        shutil.rmtree(target, ignore_errors=True)
        target.mkdir(parents=True)
        for name in PARKED_FILES:
            if (folder / name).is_file():
                shutil.copy2(folder / name, target / name)
        # the held-out evaluations of this very checkpoint (``rl.evaluate.evaluate_many``'s cache, written after it),
        # so that paired_eval.py reads a parked student's back in the next sitting instead of evaluating it again
        checkpoint = folder / "checkpoint.pt"
        for cache in folder.glob("heldout_*.json") if checkpoint.is_file() else ():
            if heldout_current(cache, checkpoint):
                shutil.copy2(cache, target / cache.name)

    for cfg, student in zip(cfgs, students):
        out = Path(cfg.out)
        record = out / "run.json"
        if not record.exists():  # never trained (interrupted before its first checkpoint): nothing to keep
            continue
        if json.loads(record.read_text())["frames"] < cfg.frames:
            copy(out)
            if student is not None:
                copy(Path(student.out))
        else:
            shutil.rmtree(committed / out.name, ignore_errors=True)
    folders = [f for f in committed.iterdir() if f.is_dir()] if committed.exists() else []
    parked = sorted(f.name for f in folders if _unfinished(f))
    starts = [_config(committed / name).get("init_from") for name in parked]
    wanted = {Path(start).parent.name for start in starts if start}
    for folder in folders:
        if folder.name not in parked and folder.name not in wanted:
            shutil.rmtree(folder)
    return sorted([*parked, *wanted])


def _unfinished(folder: Path) -> bool:
    """A parked RL run (not a student): its checkpoint holds fewer frames than its config asks for."""
    record = folder / "run.json"
    if not record.exists() or not (folder / "checkpoint.pt").is_file():
        return False
    done = json.loads(record.read_text())
    return "frames" in done["config"] and done["frames"] < done["config"]["frames"]


def _config(folder: Path) -> dict:
    record = folder / "run.json"
    return json.loads(record.read_text())["config"] if record.exists() else {}


@dataclasses.dataclass
class Flags:
    """This script's own flags (--no-committed is written by hand: a boolean field would also make --no-no-committed);
    the shared ones come from the harness, the learner's from PPOConfig."""

    recipe: str = dataclasses.field(default="reverse_bc", metadata={"choices": list(RECIPES), "help": "the recipe"})
    students_only: bool = dataclasses.field(default=False, metadata={
        "help": "a student recipe's distillation step alone (no RL), to <task>_cloud_student.json"})
    committed: Path | None = dataclasses.field(default=None, metadata={
        "help": "where unfinished runs are parked between sittings (None: "
                f"{IN_PROGRESS.relative_to(IN_PROGRESS.parents[2])}; with another --results: <results>/in_progress)"})
    refresh_curves: bool = dataclasses.field(default=False, metadata={
        "help": "only rewrite the JSON's per-batch curves from the runs' checkpoints (no training)"})


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    harness.options(parser, "task", "obs")
    add_config_arguments(parser, Flags, overrides=False)
    harness.options(parser, "jobs", seeds=[0, 1], frames=1_000_000, runs=Path("runs/curriculum"),
                    helps={"frames": "online frames per seed (at most)", "jobs": "seeds trained at once"})
    add_config_arguments(parser, ppo.PPOConfig, names=["max_minutes", "workers", "device"], defaults={"workers": 1},
                         overrides=False, helps={
                             "max_minutes": "stop each seed's training after this (minutes)",
                             "workers": "collector processes per seed (PPO; 1: collect in the training process, as "
                                        "every committed run did; frames_per_batch 4000 must be a multiple)",
                             "device": "where each seed's networks train (PPO): cpu, cuda or auto"})
    harness.options(parser, "eval_episodes", "note")
    harness.options(parser, results=RESULTS)
    parser.add_argument("--no-committed", action="store_true",
                        help="never copy parked runs (--committed) into --runs, nor park any there")
    args = parser.parse_args(argv)
    if args.refresh_curves:
        return refresh_curves(args.results / f"{args.task}_{args.obs}_{args.recipe}.json", Path(args.runs), args.note)
    if fast_mode() and args.results == RESULTS:  # never overwrite the committed evidence with a smoke run
        raise ValueError("fast mode writes smoke results: pass --results elsewhere")
    path = args.results / f"{args.task}_{args.obs}_{args.recipe}.json"
    committed = args.committed or (IN_PROGRESS if args.results == RESULTS else args.results / "in_progress")
    cfgs = [config(args.task, args.obs, args.recipe, s, args.frames, args) for s in args.seeds]
    students = [student_config(args.task, s, args, args.recipe) if RECIPES[args.recipe].get("student") else None
                for s in args.seeds]
    runs = [run for run in [*students, *([] if args.students_only else cfgs)] if run is not None]
    for run in [] if args.no_committed else runs:
        adopt_committed(Path(run.out), committed)
    for student in filter(None, students):
        if not (Path(student.out) / "run.json").exists():
            print(f"{Path(student.out).name}: no student yet, distilled first (beside another on 2 cores: "
                  "~30 min a faucet student, 37-47 min a toilet one; an interrupted one continues from its last round)")
    if args.students_only:
        if not students[0] or args.obs != "cloud":
            raise ValueError("--students-only needs a student recipe (e.g. student_anchored) and --obs cloud")
        return distil_students(students, args.results / f"{args.task}_cloud_{student_name(args.recipe)}.json",
                               argv, args.note, args.jobs)
    summary = {"task": args.task, "obs": args.obs, "recipe": args.recipe, "settings": RECIPES[args.recipe],
               **({"student": dataclasses.asdict(students[0]) | {"seed": None, "out": None}} if students[0] else {}),
               "preset": "fast" if learner_name(cfgs[0]) == "ppo" else "SACConfig defaults", "eval_episodes_per_object": cfgs[0].eval_episodes, "eval_seed": cfgs[0].eval_seed,
               "per_seed": [], **provenance(__file__, argv),
               "machine": {**machine_info(), "torch_threads": torch.get_num_threads()},
               "jobs": args.jobs, "workers": args.workers, "device": args.device,
               **({"note": args.note} if args.note else {})}
    # a continued run's earlier parts may have run on other machines: their records are kept, oldest first
    earlier, this_machine = (json.loads(path.read_text()) if path.exists() else None), summary["machine"]
    grid = [{"job": job} for job in zip(cfgs, students)]
    for row in harness.each(run_seed, grid, jobs=args.jobs, desc="seeds"):  # stopped: no worker outlives it
        summary["per_seed"].append(row)
        summary.pop("earlier_machines", None)
        summary.update(machine_records(this_machine, earlier, summary["per_seed"]))
        for key in ("frames", "demo_frames", "seen_success", "unseen_success"):
            summary[key] = sum(r[key] for r in summary["per_seed"]) / len(summary["per_seed"])
        write_json(path, summary)
        print(f"seed {row['seed']}: {row['frames']} frames, seen {row['seen_success']:.2f}, "
              f"unseen {row['unseen_success']:.2f} -> {path}")
    if not args.no_committed:
        parked = park(cfgs, students, committed)
        print(f"parked in {committed} (commit it; the same command continues): {', '.join(parked) or 'nothing'}")
    return summary


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:  # Ctrl-C or kill: the workers are stopped; what they checkpointed continues
        print("curriculum_runs: interrupted (the same command continues from the checkpoints)", file=sys.stderr)
        raise SystemExit(130)
