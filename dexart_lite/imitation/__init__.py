"""Expert -> student distillation: behaviour cloning or DAgger into the PPO actor-critic (``distill``), on the
scripted-expert demonstrations of ``dexart_lite.demos`` (a layer below both ``rl`` and ``imitation``, which
both read them: ``imitation`` imports ``rl``, never the other way)."""
