"""What a seeded result depends on besides the code: the interpreter, the processor and the
numerical libraries' versions.

The same code and seed give the same bits only with the same floating point: another
processor (its vector instructions) or another version of numpy, numba, pymunk, OpenCV or
torch may order or round a computation otherwise. Training manifests record
:func:`library_versions` (``versions``) and fingerprint files record it too, so that a
difference can be told from a change of the code.
"""

from __future__ import annotations

import platform
from importlib import metadata

__all__ = ["cpu_model", "library_versions", "differing_versions"]

#: Key in the record -> the distributions that provide it, the first installed one counting.
_DISTRIBUTIONS = {
    "numpy": ("numpy",),
    "numba": ("numba",),
    "pymunk": ("pymunk",),
    "opencv": ("opencv-contrib-python-headless", "opencv-python-headless", "opencv-contrib-python", "opencv-python"),
    "gymnasium": ("gymnasium",),
    "pettingzoo": ("pettingzoo",),
    "stable_baselines3": ("stable-baselines3",),
    "sb3_contrib": ("sb3-contrib",),
    "torch": ("torch",),
    "torchrl": ("torchrl",),
    "tensordict": ("tensordict",),
    "ray": ("ray",),
}


def cpu_model() -> str:
    """The processor's model name (Linux's ``/proc/cpuinfo``, else ``platform.processor()``;
    ``"unknown"`` when neither says)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def library_versions() -> dict[str, str]:
    """Python's version, the machine's architecture and processor (:func:`cpu_model`), and the
    installed version of each library of :data:`_DISTRIBUTIONS` (read from the package
    metadata, nothing imported; one not installed is left out)."""
    versions = {"python": platform.python_version(), "machine": platform.machine(), "cpu": cpu_model()}
    for key, distributions in _DISTRIBUTIONS.items():
        for distribution in distributions:
            try:
                versions[key] = metadata.version(distribution)
            except metadata.PackageNotFoundError:
                continue
            break
    return versions


def differing_versions(a: object, b: object) -> list[tuple[str, str, str]]:
    """``(key, a's, b's)`` for every key both records hold with another value (a record that
    is not a mapping, as from before records were kept, holds none)."""
    if not isinstance(a, dict) or not isinstance(b, dict):
        return []
    return [(key, a[key], b[key]) for key in sorted(set(a) & set(b)) if a[key] != b[key]]
