"""The adapters of the simulation core to learning APIs (see ``docs/design.md``).

:mod:`moma_env.env.parallel` (the PettingZoo parallel env), :mod:`moma_env.env.factory`
(constructors by configuration or task name), :mod:`moma_env.env.config` (``EnvConfig``,
``RewardConfig``), :mod:`moma_env.env.centralised` (the team as one Gymnasium agent),
:mod:`moma_env.env.actions`, :mod:`moma_env.env.rewards`, :mod:`moma_env.env.observations`
and the rendering. Nothing is imported here: import the module you need.
"""
