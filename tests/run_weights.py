"""The policy weights of a finished training run, for the tests that compare runs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import torch
from sb3_contrib import MaskablePPO


def final_weights(folder: Path, manifest: dict[str, Any]) -> dict[str, torch.Tensor]:
    """The policy's weights in the final checkpoint of the MaskablePPO run in ``folder``."""
    return MaskablePPO.load(folder / manifest["model"], device="cpu").policy.state_dict()
