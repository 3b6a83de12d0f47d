"""Adapters of moma_env to other frameworks' interfaces, each imported on demand.

* :mod:`.rllib`: RLlib (Ray's reinforcement learning library, the ``ray`` extra): every
  configuration registered with ``ray.tune.register_env``, the policy mapping, the
  action masks of the switching mode, and the PPO configuration of both routes.
* :mod:`.rllib_env`: the PettingZoo env of an RLlib ``env_config``, masks in the observations (no Ray import).
* :mod:`.rllib_masking`: an RLlib PPO module that acts only among the unmasked actions.
* :mod:`.rllib_vector`: the batched env (one camera measurement for all copies) as
  RLlib's multi-agent vector env, through an env runner that builds it.

Importing this package imports nothing; each module imports Ray itself.
"""
