"""Controllers as the benchmark and the training envs run them, learned ones included.

A layer of its own (above the envs, below the benchmark) so that the benchmark, the
scenario-mix training env and the ``ppo:`` controller import them without an import circle:
:mod:`~rover_env.policies.controllers` (the ``EnvController`` protocol, the classical
controllers, ``make_controller`` and the spec parser), :mod:`~rover_env.policies.residual`
(the learned agents' action mappings: residual and gain schedule) and
:mod:`~rover_env.policies.ppo` (the stable-baselines3 policy, loaded lazily: the one module
here allowed torch).
"""
