"""An env's steps call each kernel with one set of argument types, so that numba compiles it once.

A read-only array is another type to numba than a writable one, and a column of a matrix
another than a contiguous vector: each is another compilation of the kernel and of every
kernel it calls. A frame measured alone and frames measured together pass the camera's
kernels the same writable tables (moma_env.camera.geometric); the estimator's error
propagation passes writable stacks of Jacobians, even empty ones, and a rotation to
project is made contiguous (moma_env.geometry.project_to_rotation).
"""

from __future__ import annotations

import json
import subprocess
import sys

PROGRAM = """
import json, numpy as np
from moma_env import vector
from moma_env import geometry
from moma_env.camera import kernels
from moma_env.estimator import uncertainty
rng = np.random.default_rng(0)
for copies in (1, 3):  # one frame a step, then three frames a step
    envs = vector.make("top_observer", copies, action_mode="switching", camera={"pnp_warm_start": True})
    envs.reset(seed=0)
    for _ in range(60):
        envs.step(envs.sample_actions(rng))
kernels_used = {"project_markers": kernels.project_markers, "solve_boards": kernels.solve_boards,
                "polar_rotation_kernel": geometry.polar_rotation_kernel, "covariance_kernel": uncertainty.covariance_kernel}
print(json.dumps({name: len(kernel.signatures) for name, kernel in kernels_used.items()}))
"""


def test_an_envs_steps_compile_each_kernel_once():
    done = subprocess.run([sys.executable, "-c", PROGRAM], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    counts = json.loads(done.stdout.strip().splitlines()[-1])
    assert counts == {"project_markers": 1, "solve_boards": 1, "polar_rotation_kernel": 1, "covariance_kernel": 1}, counts
