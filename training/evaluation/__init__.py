"""Evaluation harness: run a policy for N episodes, measure, aggregate, report.

* :mod:`.policies`: the :class:`Policy` protocol and :func:`load_policy` (``"scripted"``,
  ``"random"``, the hook for trained policies).
* :mod:`.episode`: :func:`run_episode` records one episode from the infos' truth.
* :mod:`.harness`: :func:`evaluate` (the importable core) and :func:`summarise`.
* :mod:`.report`: files (JSON, CSV, TUM, figure) and the printed table.
* :mod:`.video`: :class:`GifRecorder`, an animated GIF of the first episode.

The command line (``moma-env evaluate``) lives in :mod:`training.cli`.
"""

from training.evaluation.episode import EpisodeResult, RobotEpisode, run_episode
from training.evaluation.harness import EvaluationResult, evaluate, summarise
from training.evaluation.policies import BUILTIN_POLICIES, Policy, PolicyEnvError, PolicyLoadError, load_policy, policy_label

__all__ = [
    "BUILTIN_POLICIES",
    "EpisodeResult",
    "EvaluationResult",
    "Policy",
    "PolicyEnvError",
    "PolicyLoadError",
    "RobotEpisode",
    "evaluate",
    "load_policy",
    "policy_label",
    "run_episode",
    "summarise",
]
