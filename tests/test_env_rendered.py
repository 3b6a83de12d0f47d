"""The environment with the rendered camera backend and the observer's pixel observation."""

from __future__ import annotations

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from moma_env.camera import CameraConfig, FloorConfig, GeometricCamera, RenderConfig, RenderedCamera
from moma_env.config import ConfigError
from moma_env.env.centralised import CentralisedTeamEnv
from moma_env.env.config import EnvConfig
from moma_env.env.factory import parallel_env

#: A small observer camera (same field of view as the default 720x576, fx 420)
#: keeps these tests fast; the benchmark measures the full PAL size.
SMALL_CAMERA = CameraConfig(width=240, height=192, fx=140.0)
IMAGE_SIZE = (48, 40)


def rendered_env(**kwargs):
    kwargs.setdefault("camera", SMALL_CAMERA)
    kwargs.setdefault("floor", FloorConfig(extent=(-2.0, -2.0, 5.0, 5.0), px_per_m=100.0))
    return parallel_env("top_observer", camera_backend="rendered", **kwargs)


def test_rendered_env_passes_the_parallel_api_test() -> None:
    env = rendered_env(action_mode="velocity", observer_image=IMAGE_SIZE)
    parallel_api_test(env, num_cycles=15)


def test_rendered_cameras_feed_the_estimator() -> None:
    env = rendered_env()
    env.reset(seed=0)
    assert all(isinstance(c, RenderedCamera) for c in env.cameras.values())
    assert {d.board_id for d in env.detections} == {0, 1}
    for _ in range(10):
        env.step({a: 0 for a in env.agents})
    for ugv in ("ugv_0", "ugv_1"):
        assert env.localisation_error(ugv) < 0.02


def test_pixel_observation_is_the_downscaled_frame_inside_its_space() -> None:
    env = rendered_env(action_mode="velocity", observer_image=IMAGE_SIZE)
    obs, _ = env.reset(seed=1)
    space = env.observation_space("observer")
    camera = env.cameras[env.scenario.world.uav.camera_name]
    for _ in range(3):
        assert space.contains(obs["observer"])
        image = obs["observer"]["image"]
        assert image.shape == (40, 48, 1) and image.dtype == np.uint8
        # The frame averaged down: same mean brightness, and not a blank image.
        assert abs(float(image.mean()) - float(camera.last_image.mean())) < 2.0
        assert image.std() > 5.0
        obs, *_ = env.step({a: env.action_space(a).sample() for a in env.agents})
    # The UGVs' observations are unchanged vectors.
    assert env.observation_space("ugv_0").shape == obs["ugv_0"].shape


def test_default_env_is_geometric_with_vector_observations() -> None:
    env = parallel_env("top_observer", action_mode="velocity")
    env.reset(seed=0)
    assert all(isinstance(c, GeometricCamera) for c in env.cameras.values())
    assert env.observation_space("observer").shape is not None
    assert EnvConfig().camera_backend == "geometric" and EnvConfig().observer_image is None


def test_env_config_rejects_bad_camera_options() -> None:
    with pytest.raises(ConfigError, match="env.camera_backend"):
        EnvConfig(camera_backend="raytraced")
    with pytest.raises(ConfigError, match="env.render"):
        EnvConfig(render=RenderConfig())
    with pytest.raises(ConfigError, match="env.floor"):
        EnvConfig(floor=FloorConfig())
    with pytest.raises(ConfigError, match="env.observer_image"):
        EnvConfig(action_mode="velocity", observer_image=(64, 48))  # geometric: no image
    with pytest.raises(ConfigError, match="env.observer_image"):
        EnvConfig(camera_backend="rendered", observer_image=(64, 48))  # switching: observer is no agent
    with pytest.raises(ConfigError, match="env.observer_image.width"):
        EnvConfig(camera_backend="rendered", action_mode="velocity", observer_image=(0, 48))
    with pytest.raises(ConfigError, match="render.noise_std"):
        rendered_env(render={"noise_std": -1.0})
    with pytest.raises(ValueError, match="centralised"):
        CentralisedTeamEnv(rendered_env(action_mode="velocity", observer_image=IMAGE_SIZE))


def test_each_of_several_observers_sees_its_own_camera_frame() -> None:
    env = rendered_env(action_mode="velocity", observer_image=IMAGE_SIZE, observer=("quadcopter", "quadcopter"), observer_spacing=0.6)
    obs, _ = env.reset(seed=2)
    for agent, uav in zip(env.observer_agents, env.scenario.world.uavs):
        assert env.observation_space(agent).contains(obs[agent])
        frame = env.cameras[uav.camera_name].last_image
        assert abs(float(obs[agent]["image"].mean()) - float(frame.mean())) < 2.0
    # the two observers stand 0.6 m apart: their images differ
    assert not np.array_equal(obs["observer_0"]["image"], obs["observer_1"]["image"])
