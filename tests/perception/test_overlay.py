"""foldbot.perception.overlay: readable labels, the expected outline drawn where the camera sees
it, and contact sheets."""

import numpy as np
import pytest

from foldbot.perception.overlay import EXPECTED_RGB, _text, contact_sheet, draw_overlay


def test_a_labels_outline_stays_on_its_text():
    img = np.full((40, 240, 3), 128, np.uint8)
    _text(img, "near_right 0.97", (10, 25), (255, 255, 0))
    coloured = np.flatnonzero((img[..., 0] > 200).any(axis=0))
    dark = np.flatnonzero((img.max(axis=2) < 60).any(axis=0))
    assert coloured.size and dark.size
    # The black outline surrounds the text by a pixel; it does not drift past its end.
    assert dark.min() >= coloured.min() - 2
    assert dark.max() <= coloured.max() + 2


def test_contact_sheet_tiles_captioned_images_in_rows():
    images = [np.full((40, 60, 3), 50 * k, np.uint8) for k in range(5)]
    sheet = contact_sheet(images, [f"step {k}" for k in range(5)], columns=2, scale=0.5)
    # 3 rows of 2 tiles, each 30 wide and 20 + 20 (caption bar) high; the 6th tile is blank.
    assert sheet.shape == (3 * 40, 2 * 30, 3) and sheet.dtype == np.uint8
    assert (sheet[20 + 40 * 2 + 5, 30 + 5] == 0).all()  # the padding tile
    assert (sheet[20 + 5, 30 + 5] == 50).all()  # image 1, right of image 0
    assert (sheet[0:20, 0:30].max(axis=2) > 200).any()  # the caption's white text


@pytest.mark.parametrize(
    ("images", "captions", "kwargs", "needle"),
    [
        ([], [], {}, "at least one image"),
        ([np.zeros((4, 4, 3), np.uint8)], [], {}, "1 images but 0 captions"),
        ([np.zeros((4, 4, 3), np.uint8)] * 2, ["a", "b"], {"columns": 0}, "columns"),
        ([np.zeros((4, 4, 3), np.uint8)], ["a"], {"scale": 2.0}, "scale"),
        ([np.zeros((4, 4, 3), np.uint8), np.zeros((4, 5, 3), np.uint8)], ["a", "b"], {}, "image 1"),
    ],
)
def test_contact_sheet_names_bad_input(images, captions, kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        contact_sheet(images, captions, **kwargs)


def test_expected_outline_is_drawn_where_the_camera_sees_it():
    from foldbot.perception.geometry import project_points
    from foldbot.perception.state import ClothState
    from foldbot.types import CameraIntrinsics, Observation

    K = np.array([[500.0, 0.0, 80.0], [0.0, 500.0, 60.0], [0.0, 0.0, 1.0]])
    intr = CameraIntrinsics(width=160, height=120, K=K)
    # A camera 1 m above the origin looking straight down (camera z = world −z).
    T = np.eye(4)
    T[:3, :3] = np.diag([1.0, -1.0, -1.0])
    T[2, 3] = 1.0
    obs = Observation(
        rgb=np.zeros((120, 160, 3), np.uint8),
        depth=np.ones((120, 160), np.float32),
        intrinsics=intr,
        T_world_camera=T,
    )
    square = np.array([[-0.05, -0.05, 0], [0.05, -0.05, 0], [0.05, 0.05, 0], [-0.05, 0.05, 0]])
    img = draw_overlay(obs, ClothState.not_detected(shape=(120, 160)), expected_outline=square)
    orange = (np.abs(img.astype(int) - EXPECTED_RGB) <= 40).all(axis=2)
    uv, _ = project_points(square, intr, T)
    for u, v in np.rint(uv).astype(int):  # each corner of the square is drawn
        assert orange[v - 1 : v + 2, u - 1 : u + 2].any()
    assert not orange[60, 80]  # not filled
