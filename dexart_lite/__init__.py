"""dexart_lite: the DexArt benchmark (CVPR 2023) in PyBullet, with a torchrl learning stack.

Importing the package registers the four gymnasium ids listed in ``ENV_IDS``:

    import gymnasium as gym
    import dexart_lite
    env = gym.make("DexArtLite/Laptop-v0", split="unseen")
"""

__version__ = "0.1.0"

from dexart_lite.registration import ENV_IDS, HORIZON, TASKS, env_id, register_all  # noqa: E402

register_all()

__all__ = ["ENV_IDS", "HORIZON", "TASKS", "__version__", "env_id"]
