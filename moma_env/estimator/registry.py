"""Estimators by name: ``"moma"`` (the paper's), ``"fused"``, ``"ekf"``, ``"graph"``, ``"graph_vision"``.

Each name gives a *localiser factory*, ``factory(EstimatorConfig) -> localiser``,
as :class:`moma_env.sim.Simulation` and ``EnvConfig.localiser`` take it; the
simulation builds one localiser per episode from the scenario's
:class:`~moma_env.estimator.EstimatorConfig`.

* ``moma``: :class:`~moma_env.estimator.MomaEstimator` as configured (the default).
* ``fused``: the same estimator with ``fusion="information"``: several references
  or cameras fused by their covariances (:mod:`moma_env.estimator.fusion`).
* ``ekf``: :class:`~moma_env.estimator.ekf.EkfLocaliser`, EKF cooperative
  localisation of the same detections with wheel odometry when it is given.
* ``graph``: :class:`~moma_env.estimator.graph.GraphLocaliser`, pose-graph MOMA
  smoothed by GTSAM's iSAM2 (the optional ``graph`` extra: ``pip install gtsam``),
  with wheel-odometry factors when it is given;
* ``graph_vision``: the same pose graph of the detections alone.

The factories are module-level, so an env holding one stays picklable; the
modules behind ``ekf`` and ``graph`` are imported on first use, so that
``gtsam`` is needed only by who asks for the graph.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from moma_env.config import ConfigError
from moma_env.estimator.config import EstimatorConfig
from moma_env.estimator.moma import MomaEstimator

__all__ = ["ESTIMATORS", "fused_estimator", "localiser_factory", "resolve_localiser", "check_estimator_name"]


def fused_estimator(config: EstimatorConfig) -> MomaEstimator:
    """The MOMA estimator with information-weighted fusion (``config`` otherwise unchanged)."""
    if not isinstance(config, EstimatorConfig):
        raise TypeError(f"config must be an EstimatorConfig, got {type(config).__name__}")
    return MomaEstimator(dataclasses.replace(config, fusion="information"))


def _moma():
    return MomaEstimator


def _fused():
    return fused_estimator


def _ekf():
    from moma_env.estimator.ekf import EkfLocaliser

    return EkfLocaliser


def _graph():
    from moma_env.estimator.graph import GraphLocaliser

    return GraphLocaliser


def _graph_vision():
    from moma_env.estimator.graph import graph_vision

    return graph_vision


#: Name -> a function returning the factory (its module imported on first use).
ESTIMATORS: dict[str, Callable[[], Callable[[EstimatorConfig], Any]]] = {
    "moma": _moma,
    "fused": _fused,
    "ekf": _ekf,
    "graph": _graph,
    "graph_vision": _graph_vision,
}


def check_estimator_name(field: str, name: Any) -> str:
    """``name`` if it names an estimator of :data:`ESTIMATORS`, else ConfigError naming ``field``."""
    if not isinstance(name, str) or name not in ESTIMATORS:
        raise ConfigError(field, f"unknown estimator {name!r}; expected one of {list(ESTIMATORS)}")
    return name


def localiser_factory(name: str) -> Callable[[EstimatorConfig], Any]:
    """The localiser factory of estimator ``name`` (ConfigError for an unknown name;
    ImportError naming the extra to install when an optional dependency is missing)."""
    return ESTIMATORS[check_estimator_name("estimator", name)]()


def resolve_localiser(spec: str | Callable[[EstimatorConfig], Any] | None) -> Callable[[EstimatorConfig], Any]:
    """The localiser factory ``spec`` names or is: an estimator name (:func:`localiser_factory`),
    a factory itself, or None for the MOMA estimator (what a simulation given none runs)."""
    if spec is None:
        return MomaEstimator
    if isinstance(spec, str):
        return localiser_factory(spec)
    return spec
