"""Expert -> student distillation: scripted-expert demonstrations (``demos``) and behaviour cloning
or DAgger into the PPO actor-critic (``distill``)."""
