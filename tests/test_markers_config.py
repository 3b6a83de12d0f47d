"""Board layouts and configuration validation."""

from dataclasses import dataclass

import numpy as np
import pytest

from moma_env.config import ConfigError, check_positive, from_mapping
from moma_env.markers import BoardLayout, board_for_robot


def test_default_board_matches_the_real_robots():
    b = board_for_robot(1)
    assert b.marker_ids == (4, 5, 6, 7)
    assert b.width == pytest.approx(0.34) and b.height == pytest.approx(0.34)
    pts = b.marker_corners
    assert pts.shape == (4, 4, 3)
    # Centred on the board, in the z = 0 plane.
    np.testing.assert_allclose(pts.reshape(-1, 3).mean(axis=0), [0, 0, 0], atol=1e-12)
    # Marker 0 is top-left; its corners go TL, TR, BR, BL (x right, y up on the face).
    np.testing.assert_allclose(pts[0], [[-0.17, 0.17, 0], [-0.01, 0.17, 0], [-0.01, 0.01, 0], [-0.17, 0.01, 0]], atol=1e-12)
    # Each marker side is 16 cm.
    assert np.linalg.norm(pts[3, 1] - pts[3, 0]) == pytest.approx(0.16)


def test_object_points_mask_selects_markers():
    b = BoardLayout()
    pts = b.object_points([True, False, False, True])
    assert pts.shape == (8, 3)
    np.testing.assert_allclose(pts[4:], b.marker_corners[3])


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"marker_size": 0.0}, "board.marker_size"),
        ({"gap": -0.01}, "board.gap"),
        ({"marker_ids": (0, 1, 2)}, "board.marker_ids"),
        ({"marker_ids": (0, 1, 1, 2)}, "board.marker_ids"),
        ({"marker_ids": (0, 1, 2, 99)}, "board.marker_ids"),
        ({"dictionary": "DICT_NOPE"}, "board.dictionary"),
    ],
)
def test_bad_board_raises_naming_the_field(kwargs, field):
    with pytest.raises(ConfigError) as err:
        BoardLayout(**kwargs)
    assert err.value.field == field
    assert field in str(err.value)


@dataclass(frozen=True)
class _Inner:
    size: float = 1.0

    def __post_init__(self):
        check_positive("inner.size", self.size)


@dataclass(frozen=True)
class _Outer:
    name: str = "x"
    inner: _Inner = _Inner()


def test_from_mapping_builds_nested_and_rejects_unknown_keys():
    cfg = from_mapping(_Outer, {"name": "y", "inner": {"size": 2.0}})
    assert cfg == _Outer("y", _Inner(2.0))
    with pytest.raises(ConfigError, match="inner.colour"):
        from_mapping(_Outer, {"inner": {"colour": 1}})
    with pytest.raises(ConfigError, match="inner.size"):
        from_mapping(_Outer, {"inner": {"size": -1}})
    with pytest.raises(ConfigError, match="nmae"):
        from_mapping(_Outer, {"nmae": "typo"})


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), "abc", None])
def test_check_positive_rejects_non_numbers(bad):
    with pytest.raises(ConfigError, match="field"):
        check_positive("field", bad)
