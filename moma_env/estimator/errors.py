"""Errors raised by the MOMA estimator at its boundary.

Configuration errors are the project's ``moma_env.config.ConfigError`` (its
``field`` names the offending field); this module adds the errors for ids the
estimator was never told about.
"""

from __future__ import annotations

__all__ = [
    "UnknownIdError",
    "UnknownRobotError",
    "UnknownBoardError",
    "UnknownCameraError",
]


class UnknownIdError(KeyError):
    """An id (robot name, board id or camera id) the estimator was never told about.

    A ``KeyError`` whose message reads normally (``KeyError`` would quote it).
    ``key`` holds the unknown id.
    """

    kind = "id"

    def __init__(self, key: object, known: object = ()):
        self.key = key
        self.message = f"unknown {self.kind} {key!r}; known: {sorted(known, key=repr)!r}"
        super().__init__(self.message)

    def __str__(self) -> str:
        return self.message


class UnknownRobotError(UnknownIdError):
    """A robot name that was never added with ``add_robot``."""

    kind = "robot"


class UnknownBoardError(UnknownIdError):
    """A detection's ``board_id`` that no robot carries."""

    kind = "board id"


class UnknownCameraError(UnknownIdError):
    """A detection's (or a query's) ``camera_id`` that no robot carries."""

    kind = "camera id"
