"""A frame measured alone and frames measured together call the camera's kernels with the same
argument types, so that numba compiles each kernel once: moma_env.camera.geometric keeps the
tables it passes them writable, like those a batch of frames stacks (a read-only array is
another type to numba, and another compilation of the kernel and of every kernel it calls).
"""

from __future__ import annotations

import json
import subprocess
import sys

PROGRAM = """
import json, numpy as np
from moma_env import vector
from moma_env.camera import kernels
rng = np.random.default_rng(0)
for copies in (1, 3):  # one frame a step, then three frames a step
    envs = vector.make("top_observer", copies, action_mode="switching", camera={"pnp_warm_start": True})
    envs.reset(seed=0)
    for _ in range(30):
        envs.step(envs.sample_actions(rng))
print(json.dumps({name: len(getattr(kernels, name).signatures) for name in ("project_markers", "solve_boards")}))
"""


def test_one_frame_and_a_batch_of_frames_compile_each_camera_kernel_once():
    done = subprocess.run([sys.executable, "-c", PROGRAM], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert counts == {"project_markers": 1, "solve_boards": 1}, counts
