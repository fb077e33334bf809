"""Controller benchmark: named scenarios, one seed plan, metrics with confidence intervals.

``rover-env benchmark --controllers open-loop,slip-pi[,ppo:PATH] --scenarios all --episodes N
--out DIR`` runs every controller through ``ProtoExplorerEnv`` on every scenario of
``configs/scenarios`` for the same seeds and writes Markdown and CSV tables and PNG plots.
Nothing here imports torch unless a learned (``ppo:``, ``sac:``, ``td3:``) controller is asked
for. The seed plan: :mod:`rover_env.seeds`.
"""
