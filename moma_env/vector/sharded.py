"""A batched env whose copies are stepped by several processes: :class:`ShardedVectorEnv`.

``make(name, num_envs, workers=W)`` splits the ``num_envs`` copies into ``W``
contiguous shards (sizes differing by at most one, the first ones larger), each a
:class:`~moma_env.vector.env.MomaVectorEnv`: the first in this process, the
others in ``W - 1`` worker processes. A step sends every worker its rows of the
actions, steps the first shard here meanwhile, and joins the results in copy
order, so the batch has the interface and the episodes of one
:class:`MomaVectorEnv` of ``num_envs`` copies, bit for bit: copy ``i`` is reset
with the seed it would get there (``s + i``) and runs the same code on its own
generator. What changes is the wall time: on a machine with ``W`` free cores the
copies' Python runs ``W`` at a time, and a step waits for the slowest shard and
one pipe round trip. A worker's step and reset send the small arrays of the copies'
infos as one array per place (:mod:`moma_env.vector.info_arrays`): here each is a row
view of it.

The actions, seeds and indices are checked here, before a worker is asked
(:mod:`moma_env.vector.batch_checks`: the same errors as the in-process batch).
An error in a shard is raised here with its own type and, as a note, where it was
raised (the worker and its traceback). Ctrl-C interrupts this process only (the
workers ignore SIGINT), and the next call first reads the replies the interrupted one
left. After an error or an interrupt in :meth:`step` the shards may be at different
steps, so reset before stepping on.

The workers start with the ``forkserver`` method where the platform has it (else
``spawn``): a script that makes a sharded env with ``W > 1`` must guard its main
code with ``if __name__ == "__main__":``, as for any multiprocessing pool.
"""

from __future__ import annotations

import multiprocessing as mp
import pickle
import signal
import traceback
import weakref
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from moma_env.env.parallel import MomaParallelEnv, checked_seed
from moma_env.vector.batch_checks import (
    checked_actions, checked_count, checked_index, copy_options, copy_seeds, random_actions, refuse_finished_copies,
)
from moma_env.vector.collection import deferred_collection
from moma_env.vector.env import LatestMasks, MomaVectorEnv, partial_reset
from moma_env.vector.info_arrays import lift_arrays, put_arrays

__all__ = ["ShardedVectorEnv", "copy_action_masks", "default_start_method", "send_reply", "shard_sizes"]


def default_start_method() -> str:
    """forkserver where the platform has it (workers start from a clean server process), else spawn."""
    return "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"


def shard_sizes(num_envs: int, workers: int) -> list[int]:
    """How many copies each of ``workers`` shards holds: contiguous, differing by at most one."""
    base, extra = divmod(num_envs, workers)
    return [base + (1 if k < extra else 0) for k in range(workers)]


def copy_action_masks(env: MomaParallelEnv) -> dict[str, np.ndarray]:
    """One copy's ``action_masks()`` (module level: it runs in the copy's worker)."""
    return env.action_masks()


def _run(vector: MomaVectorEnv, command: str, payload: Any) -> Any:
    """One command of the protocol on a worker's batch."""
    if command == "step":  # the actions were checked by the caller, for every shard at once
        return vector.step_checked(payload)
    if command == "reset":
        seeds, options = payload
        return vector.reset(seed=seeds, options=options)
    if command == "reset_at":
        index, seed, options = payload
        return vector.reset_at(index, seed=seed, options=options)
    if command == "action_masks":
        return vector.action_masks()
    if command == "state":
        return vector.state()
    if command == "render":
        return vector.render(payload)
    if command == "call":
        index, function, args, kwargs = payload
        return vector.call_at(index, function, *args, **kwargs)
    raise ValueError(f"unknown command {command!r}")


def _error_message(error: BaseException) -> tuple[str, Any, str]:
    """The reply of a failed command: the exception itself when it pickles, and its traceback."""
    text = traceback.format_exc()
    try:
        pickle.dumps(error)
    except Exception:  # noqa: BLE001 - an exception that does not pickle goes as its text
        return ("error", None, text)
    return ("error", error, text)


def _serve(connection, name: str, num_envs: int, options: dict[str, Any]) -> None:
    """A worker's main loop: build its batch, then answer commands until ``close``. Ctrl-C
    (SIGINT, sent to the whole process group) is left to the parent, which may go on."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        vector = MomaVectorEnv(name, num_envs, **options)
    except Exception as error:  # the parent raises it
        connection.send(_error_message(error))
        connection.close()
        return
    connection.send(("ok", None, ""))
    while True:
        try:
            command, payload = connection.recv()
        except (EOFError, OSError):  # the parent is gone
            break
        if command == "close":
            vector.close()
            connection.send(("ok", None, ""))
            break
        try:
            result = _run(vector, command, payload)
        except Exception as error:  # noqa: BLE001 - every error goes back to the parent
            connection.send(_error_message(error))
        else:
            send_reply(connection, command, result)
    connection.close()


#: The commands whose result ends with the copies' infos, sent with their arrays lifted
#: (:mod:`moma_env.vector.info_arrays`) and put back in the parent.
_LIFTED = frozenset({"step", "reset"})


def send_reply(connection: Connection, command: str, result: Any) -> None:
    """Send a command's result; a step's or reset's with its infos' arrays as columns
    (``(result, columns)``), the worker's own infos left as they were."""
    if command not in _LIFTED:
        connection.send(("ok", result, ""))
        return
    infos = result[-1]
    columns, lifted = lift_arrays(infos)
    try:
        connection.send(("ok", (result, columns), ""))
    finally:
        put_arrays(infos, columns, lifted)


class _Shard:
    """Copies ``first .. first + size - 1`` in one worker process."""

    def __init__(self, index: int, first: int, size: int, name: str, options: dict[str, Any], context: mp.context.BaseContext):
        self.index, self.first, self.size = index, first, size
        self.connection, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, name, size, options), daemon=True, name=f"moma-shard-{index}")
        self.process.start()
        child.close()
        self.awaited: deque[str] = deque(["start"])  # the commands sent and not yet answered

    def what(self) -> str:
        return f"worker {self.index} (copies {self.first}..{self.first + self.size - 1})"

    def send(self, command: str, payload: Any = None) -> None:
        self.connection.send((command, payload))
        self.awaited.append(command)

    def receive(self) -> tuple[str, Any, str]:
        """The reply to the oldest command not yet answered (a step's or reset's infos
        with their arrays put back)."""
        try:
            reply = self.connection.recv()
        except (EOFError, OSError):
            self.awaited.clear()  # nothing more will come
            return ("error", None, f"{self.what()} exited (exit code {self.process.exitcode})")
        command = self.awaited.popleft()
        status, value, text = reply
        if status == "ok" and command in _LIFTED:
            value, columns = value
            put_arrays(value[-1], columns)
        return status, value, text

    def drain(self) -> None:
        """Read the replies still owed to a call that was interrupted (Ctrl-C between the
        send and the receive), so that the next call reads its own."""
        while self.awaited:
            self.receive()

    def stop(self) -> None:
        """Ask the worker to close (joined by :func:`_stop`)."""
        try:
            self.send("close")
        except (BrokenPipeError, OSError):
            pass

    def join(self) -> None:
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(timeout=5)
        self.connection.close()


class _LocalShard:
    """The first copies, stepped in this process while the workers step theirs: a command
    is held at :meth:`send` and run at :meth:`receive`, after every worker got its own."""

    def __init__(self, size: int, name: str, options: dict[str, Any]):
        self.index, self.first, self.size = 0, 0, size
        self.vector = MomaVectorEnv(name, size, **options)
        self._command: tuple[str, Any] | None = None

    def what(self) -> str:
        return f"this process (copies 0..{self.size - 1})"

    def send(self, command: str, payload: Any = None) -> None:
        self._command = (command, payload)

    def drain(self) -> None:
        self._command = None  # a command held when the call was interrupted is dropped

    def receive(self) -> tuple[str, Any, str]:
        assert self._command is not None
        command, payload = self._command
        self._command = None
        try:
            return ("ok", _run(self.vector, command, payload), "")
        except Exception as error:  # noqa: BLE001 - raised after the workers answered
            return ("error", error, traceback.format_exc())

    def stop(self) -> None:
        self.vector.close()

    def join(self) -> None:
        pass


def _raise_first(shards: Sequence[_Shard | _LocalShard], replies: Sequence[tuple[str, Any, str]]) -> None:
    """Raise the first failed reply's error (its own type, the worker's traceback as a note)."""
    for shard, (status, value, text) in zip(shards, replies):
        if status == "ok":
            continue
        if isinstance(value, BaseException):
            value.add_note(f"raised in {shard.what()}:\n{text}")
            raise value
        raise RuntimeError(f"{shard.what()} failed:\n{text}")


def _stop(shards: Sequence[_Shard | _LocalShard]) -> None:
    """End every shard: ask the workers to close, then terminate what is still running."""
    for shard in shards:
        shard.stop()
    for shard in shards:
        shard.join()


def _join(parts: Sequence[Any]) -> Any:
    """Per-shard ``(n_k, ...)`` arrays (or dicts of them) joined along the copies."""
    if isinstance(parts[0], dict):
        return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
    return np.concatenate(parts)


class ShardedVectorEnv:
    """``num_envs`` copies of one configuration stepped by ``workers`` processes, this one
    included; see the module docstring.

    Args:
        name: configuration name (``"top_observer"``, ...).
        num_envs: number of copies (>= 1).
        workers: processes that step copies, this one included (1 <= workers <=
            num_envs; 1: no worker process).
        start_method: multiprocessing start method (default :func:`default_start_method`).
        options: options of :func:`moma_env.env.factory.parallel_env` (must pickle).

    Attributes:
        spec_env: a parallel env of the configuration in this process, for its spaces
            and layout (copy 0: read it, do not step it).
    """

    def __init__(self, name: str, num_envs: int, workers: int, *, start_method: str | None = None, **options: Any):
        self.num_envs = checked_count("num_envs", num_envs)
        workers = checked_count("workers", workers)
        if workers > self.num_envs:
            raise ValueError(f"workers must be at most num_envs={self.num_envs}, got {workers}")
        self.workers = workers
        sizes = shard_sizes(self.num_envs, workers)
        local = _LocalShard(sizes[0], name, options)  # options checked here, before any worker starts
        self.spec_env: MomaParallelEnv = local.vector.spec_env
        self._shards: list[_Shard | _LocalShard] = [local]
        context = mp.get_context(start_method or default_start_method())
        first = sizes[0]
        for k, size in enumerate(sizes[1:], start=1):
            self._shards.append(_Shard(k, first, size, name, dict(options), context))
            first += size
        self._closed = False
        self._finalizer = weakref.finalize(self, _stop, self._shards)
        _raise_first(self._shards[1:], [shard.receive() for shard in self._shards[1:]])
        self.possible_agents = list(self.spec_env.possible_agents)
        self.agents = list(self.possible_agents)
        self.metadata = dict(self.spec_env.metadata)
        self.render_mode = self.spec_env.render_mode
        self.state_space: spaces.Box = self.spec_env.state_space
        self._started = False
        self._masks_in_infos = self.spec_env.config.action_masks  # every UGV's infos carry its mask
        self._latest_masks = LatestMasks()
        #: The ``gymnasium.vector.AutoresetMode`` every shard follows (:class:`MomaVectorEnv`).
        self.autoreset_mode: AutoresetMode = local.vector.autoreset_mode
        # DISABLED: the copies whose episode ended and that were not reset since (checked here,
        # so that the error names the batch's indices, not a shard's).
        self._ended: set[int] = set()
        self._observations: dict[str, Any] | None = None  # as last returned, for a partial reset

    # ------------------------------------------------------------------ spaces
    def single_observation_space(self, agent: str) -> spaces.Space:
        """One copy's observation space of ``agent``."""
        return self.spec_env.observation_space(agent)

    def single_action_space(self, agent: str) -> spaces.Space:
        """One copy's action space of ``agent``."""
        return self.spec_env.action_space(agent)

    # ------------------------------------------------------------------ protocol
    def _ready(self) -> None:
        """Refuse a closed env; read what an interrupted call left unread."""
        if self._closed:
            raise RuntimeError("the env is closed")
        for shard in self._shards:
            shard.drain()

    def _broadcast(self, command: str, payloads: Sequence[Any]) -> list[Any]:
        """Send each shard its payload, then collect every reply (raising the first error)."""
        self._ready()
        for shard, payload in zip(self._shards, payloads):
            shard.send(command, payload)
        replies = [shard.receive() for shard in self._shards]
        _raise_first(self._shards, replies)
        return [value for _, value, _ in replies]

    def _at(self, index: object, command: str, payload: Callable[[int], Any]) -> Any:
        """One command on the shard holding copy ``index`` (``payload(local index)``), in
        this process or its worker."""
        self._ready()
        i = checked_index(index, self.num_envs)
        shard = next(s for s in self._shards if s.first <= i < s.first + s.size)
        shard.send(command, payload(i - shard.first))
        reply = shard.receive()
        _raise_first([shard], [reply])
        return reply[1]

    def _rows(self, values: Sequence[Any]) -> list[list[Any]]:
        return [list(values[s.first : s.first + s.size]) for s in self._shards]

    # ------------------------------------------------------------------ reset and step
    def reset(
        self, seed: int | Sequence[int] | None = None, options: dict | Sequence[dict | None] | None = None
    ) -> tuple[dict[str, Any], tuple[dict, ...]]:
        """Reset every copy; copy ``i`` gets the seed of :class:`MomaVectorEnv` (``seed + i``);
        ``options``: one dict for every copy or a sequence of ``num_envs``, one per copy."""
        if isinstance(options, Mapping) and "reset_mask" in options:
            self._observations, infos = partial_reset(self, self._observations, seed, options)
            return self._observations, infos
        seeds = self._rows(copy_seeds(seed, self.num_envs))
        per_copy = self._rows(copy_options(options, self.num_envs))
        self._latest_masks.drop()
        results = self._broadcast("reset", list(zip(seeds, per_copy)))
        self._ended = set()
        self._started = True
        observations = {a: _join([obs[a] for obs, _ in results]) for a in self.possible_agents}
        infos = tuple(info for _, infos in results for info in infos)
        if self._masks_in_infos:
            self._latest_masks.take(infos, self.possible_agents)
        self._observations = observations
        return observations, infos

    def reset_at(self, index: int, seed: int | None = None, options: dict | None = None) -> tuple[dict[str, Any], dict]:
        """Reset copy ``index`` alone; its observations (agent -> one copy's observation) and infos."""
        seed = checked_seed(seed)
        self._latest_masks.stale(checked_index(index, self.num_envs))
        result = self._at(index, "reset_at", lambda local: (local, seed, options))
        self._ended.discard(index)
        return result

    def step(self, actions: Mapping[str, Any]) -> tuple[dict, dict, dict, dict, tuple[dict, ...]]:
        """Step every copy with its row of ``actions`` (the shards at the same time); autoreset as
        :class:`MomaVectorEnv` (:attr:`autoreset_mode`)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        refuse_finished_copies(self.autoreset_mode, self._ended)
        # The workers' replies (every copy's infos, unpickled here) live until the next step,
        # like the local shard's: the collector waits for the end of the batch step for both.
        self._latest_masks.drop()
        with deferred_collection():
            checked = checked_actions(actions, self.possible_agents, self.single_action_space, self.num_envs)
            payloads = [{a: rows[s.first : s.first + s.size] for a, rows in checked.items()} for s in self._shards]
            results = self._broadcast("step", payloads)
            agents = self.possible_agents
            observations = {a: _join([r[0][a] for r in results]) for a in agents}
            rewards, terminations, truncations = ({a: np.concatenate([r[j][a] for r in results]) for a in agents} for j in (1, 2, 3))
            infos = tuple(info for r in results for info in r[4])
            if self._masks_in_infos:
                self._latest_masks.take(infos, agents)
            if self.autoreset_mode is AutoresetMode.DISABLED:
                self._ended = set(np.flatnonzero(np.any([terminations[a] | truncations[a] for a in agents], axis=0)).tolist())
            self._observations = observations
            return observations, rewards, terminations, truncations, infos

    def sample_actions(self, rng: np.random.Generator) -> dict[str, np.ndarray]:
        """Uniform random actions of every agent for every copy, drawn from ``rng``
        (:func:`~moma_env.vector.batch_checks.random_actions`)."""
        return random_actions(self.possible_agents, self.single_action_space, self.num_envs, rng)

    # ------------------------------------------------------------------ the rest
    def action_masks(self) -> dict[str, np.ndarray]:
        """Switching mode: agent -> ``(num_envs, n)`` int8, each copy's ``action_masks()`` (the
        ones the last reset's or step's infos carried, if they did, as :class:`MomaVectorEnv`)."""
        latest = self._latest_masks.get(self._copy_masks)
        if latest is not None:
            return latest
        parts = self._broadcast("action_masks", [None] * self.workers)
        return {a: np.concatenate([p[a] for p in parts]) for a in parts[0]}

    def _copy_masks(self, index: int) -> dict[str, np.ndarray]:
        """Copy ``index``'s ``action_masks()``, computed in its worker."""
        return self._at(index, "call", lambda local: (local, copy_action_masks, (), {}))

    def state(self) -> np.ndarray:
        """``(num_envs, state_dim)`` float32: each copy's ``state()``."""
        return np.concatenate(self._broadcast("state", [None] * self.workers))

    def render(self, index: int = 0) -> np.ndarray | None:
        """Copy ``index``'s ``render()`` (made in its worker)."""
        return self._at(index, "render", lambda local: local)

    def call_at(self, index: int, function: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """``function(env, *args, **kwargs)`` on copy ``index``'s parallel env, run in its worker
        (``function``, the arguments and the result must pickle)."""
        self._latest_masks.stale(checked_index(index, self.num_envs))
        return self._at(index, "call", lambda local: (local, function, args, kwargs))

    def close(self) -> None:
        """End the workers (idempotent)."""
        if not self._closed:
            self._closed = True
            self._finalizer()
