"""``make(name, num_envs, workers=None, **options)``: the batched env of a configuration."""

from __future__ import annotations

from typing import Any

from moma_env.vector.env import MomaVectorEnv
from moma_env.vector.sharded import ShardedVectorEnv

__all__ = ["BatchedEnv", "make"]

#: Either batched env: the same interface, the same episodes.
BatchedEnv = MomaVectorEnv | ShardedVectorEnv


def make(name: str, num_envs: int, *, workers: int | None = None, start_method: str | None = None, **options: Any) -> BatchedEnv:
    """``num_envs`` copies of configuration ``name``.

    Args:
        name: configuration name (``"top_observer"``, ...).
        num_envs: number of copies (>= 1).
        workers: None (default) steps every copy in this process
            (:class:`MomaVectorEnv`); an integer ``W`` splits the copies into ``W``
            shards stepped at the same time, one here and the others in ``W - 1``
            worker processes (:class:`~moma_env.vector.sharded.ShardedVectorEnv`),
            the same episodes bit for bit.
        start_method: with ``workers``, the multiprocessing start method of the worker
            processes (default :func:`~moma_env.vector.sharded.default_start_method`).
        options: every option of :func:`moma_env.env.factory.parallel_env` (env
            options and configuration fields).
    """
    if workers is None:
        return MomaVectorEnv(name, num_envs, **options)
    return ShardedVectorEnv(name, num_envs, workers, start_method=start_method, **options)
