"""A progress bar over episodes: tqdm when installed, else a plain stderr counter."""

from __future__ import annotations

import sys
from typing import Any, TextIO

__all__ = ["EpisodeProgress"]


class EpisodeProgress:
    """Counts finished episodes on stderr; use as a context manager.

    Args:
        total: number of episodes.
        description: label before the counter.
        stream: where to draw (default ``sys.stderr``).
    """

    def __init__(self, total: int, description: str = "episodes", stream: TextIO | None = None):
        self.total = total
        self.description = description
        self.stream = stream if stream is not None else sys.stderr
        self.done = 0
        self._bar: Any = None
        try:
            from tqdm import tqdm
        except ImportError:  # pragma: no cover - tqdm is installed in the dev venv
            tqdm = None
        if tqdm is not None:
            self._bar = tqdm(total=total, desc=description, unit="ep", file=self.stream, leave=True)

    def update(self) -> None:
        """One more episode finished."""
        self.done += 1
        if self._bar is not None:
            self._bar.update(1)
        else:
            end = "\n" if self.done == self.total else ""
            print(f"\r{self.description}: {self.done}/{self.total}", end=end, file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> EpisodeProgress:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
