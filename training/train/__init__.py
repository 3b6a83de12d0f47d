"""Training of coordination policies with Stable-Baselines3 (``moma-env train``).

* :mod:`.config`: :class:`TrainConfig`, the validated description of a run (no SB3 import).
* :mod:`.team_slots`: one env copy as one slot per UGV, and the worker-process protocol (no SB3 import).
* :mod:`.shared_vec_env`: :class:`SharedPolicyVecEnv`, the SB3 ``VecEnv`` of the shared-policy route.
* :mod:`.envs`: the vectorised envs of both routes, ``VecNormalize``.
* :mod:`.models`: the SB3 model of a run; TensorBoard when installed.
* :mod:`.checkpoint`: atomic checkpoints and the manifest.
* :mod:`.callbacks`: periodic checkpoints and held-out evaluations.
* :mod:`.evaluation`: the current model through the evaluation harness.
* :mod:`.run`: :func:`train`, a run from start to finish or resumed.
* :mod:`.command`: the ``moma-env train`` subcommand.
* :mod:`.bench`: PPO training frames per second (``moma-env bench``).

Importing this package imports nothing heavy; the modules that need SB3 import it themselves.
"""
