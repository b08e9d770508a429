"""``dexart-lite train``: PPO (``rl/ppo.py``, DexArt's learner and the default) or the off-policy learner
(``rl/sac.py``: SAC with the guide's demonstrations in its replay buffer, ``--algo sac``).

    dexart-lite train --task laptop --preset cpu --frames 60000                       # PPO
    dexart-lite train --algo sac --task laptop --obs state --frames 300000            # SAC + demonstrations
    dexart-lite train --task laptop --recipe experts --out runs/laptop_experts        # a headline's whole pipeline

The two share every flag of the same name (task, frames, lr, curriculum, guide, ...); each has its own
defaults (``PPOConfig``'s faithful preset, ``SACConfig``). A flag that only one learner has is refused by the
other, with its name, instead of being ignored.
"""

from __future__ import annotations

import argparse
from dataclasses import fields

from dexart_lite.cli import add_config_arguments
from dexart_lite.rl import ppo, recipes
from dexart_lite.rl.learners import LEARNERS
from dexart_lite.utils import check_choice

ALGOS = tuple(LEARNERS)
PPO_FIELDS, SAC_FIELDS = ({f.name for f in fields(LEARNERS[name].config)} for name in ("ppo", "sac"))
PPO_ONLY = sorted(PPO_FIELDS - SAC_FIELDS)
SAC_ONLY = sorted(SAC_FIELDS - PPO_FIELDS - {"algo"})


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--algo", default="ppo", help="ppo (DexArt's; --preset and the PPO flags) or sac (off-policy "
                        "SAC with demonstrations in the replay buffer, rl/sac.py; its own defaults)")
    ppo.add_arguments(parser)  # every PPOConfig field and --preset; defaults None (the preset's / SACConfig's apply)
    recipes.add_arguments(parser)  # --recipe: demonstrations -> student -> PPO -> final evaluation (rl/recipes.py)
    # the flags only SACConfig has (--set: ppo.add_arguments added it)
    add_config_arguments(parser.add_argument_group("sac only"), LEARNERS["sac"].config, names=SAC_ONLY,
                         given_only=True, default_label="sac default", overrides=False)


def given(args: argparse.Namespace, names: list[str]) -> list[str]:
    return ["--" + n.replace("_", "-") for n in names if getattr(args, n, None) is not None]


def run(args: argparse.Namespace) -> int:
    check_choice("algorithm (--algo)", args.algo, ALGOS)
    if args.recipe is not None:
        if args.algo != "ppo" or args.preset != "faithful":
            raise ValueError("--recipe sets the learner and its settings itself: drop --algo / --preset")
        return recipes.run(args)
    if args.algo == "ppo" and given(args, SAC_ONLY):
        raise ValueError(f"{', '.join(given(args, SAC_ONLY))}: SAC options; add --algo sac or drop them")
    wrong = given(args, PPO_ONLY) + (["--preset"] if args.preset != "faithful" else [])
    if args.algo == "sac" and wrong:
        raise ValueError(f"{', '.join(wrong)}: PPO options that --algo sac does not use")
    learner = LEARNERS[args.algo]
    result = learner.train(learner.config_from_args(args))
    print(f"checkpoint: {result['checkpoint']}\nreport:     {result['report']}\ncurve:      {result['curve']}")
    for split, res in result["eval"].items():
        print(f"{split} success: {res['success_rate']:.2f} ({res['episodes']} episodes)")
    return 0
