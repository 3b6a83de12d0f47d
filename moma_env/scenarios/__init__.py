"""Typed configurations of the paper's robot set-ups and their random generators."""

from moma_env.scenarios.base import Scenario

__all__ = ["Scenario"]
