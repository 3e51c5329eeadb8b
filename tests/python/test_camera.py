"""A camera (culling, pixels, the shaded image) and the caller's own id map."""

import numpy as np
import pytest

import viscd
from conftest import brute_sphere_pairs


def small_camera():
    return viscd.Camera(eye=(0, 0, 20), target=(0, 0, 0), width=320, height=240)


def test_camera_attributes_round_trip():
    cam = viscd.Camera((1, 2, 3), (0, 0, 0), up=(0, 0, 1), fov_y_deg=45, near=0.5, far=200, width=64, height=48)
    assert cam.eye == (1.0, 2.0, 3.0) and cam.target == (0.0, 0.0, 0.0) and cam.up == (0.0, 0.0, 1.0)
    assert (cam.fov_y_deg, cam.near, cam.far, cam.width, cam.height) == (45.0, 0.5, 200.0, 64, 48)
    cam.eye = np.array([0, 0, 9.5])
    assert cam.eye == (0.0, 0.0, 9.5)
    assert "viscd.Camera(eye=(0, 0, 9.5)" in repr(cam)


def test_culling_by_pixels(backend):
    # Two overlapping near spheres (active) and two overlapping far tiny ones (culled).
    spheres = np.float32([[0, 0, 0, 3], [2, 0, 0, 3], [0, 0, -400, 0.05], [0.05, 0, -400, 0.05]])
    det = viscd.Detector(backend, lambda_=50)
    frame = det.detect(spheres, camera=small_camera())
    np.testing.assert_array_equal(frame.state, [2, 2, 0, 0])
    np.testing.assert_array_equal(frame.pairs, [[0, 1]])
    assert frame.pixels.dtype == np.float32 and frame.pixels.shape == (4,)
    assert frame.pixels[0] >= 50 and frame.pixels[2] < 50
    s = frame.stats
    assert s["has_camera"] and s["has_pixels"] and s["active"] == 2 and s["mean_pixels"] > 0
    # always_active keeps the far pair in.
    kept = det.detect(spheres, camera=small_camera(), always_active=np.bool_([0, 0, 1, 1]))
    np.testing.assert_array_equal(kept.pairs, [[0, 1], [2, 3]])
    # Without culling every object is active; the pairs are the brute force's.
    off = viscd.Detector(backend, culling=False).detect(spheres, camera=small_camera())
    np.testing.assert_array_equal(off.pairs, brute_sphere_pairs(spheres))


def test_shaded_image():
    det = viscd.Detector(shade=True, lambda_=1)
    spheres = np.float32([[0, 0, 0, 3], [2, 0, 0, 3], [-8, 0, 0, 1]])
    frame = det.detect(spheres, camera=small_camera())
    img = frame.image
    assert img.shape == (240, 320, 4) and img.dtype == np.uint8
    centre = img[120, 160 + 10, :3]  # on sphere 1, colliding: red
    assert centre[0] > 150 and centre[2] < 100
    assert viscd.Detector().detect(spheres, camera=small_camera()).image is None


def test_caller_id_map():
    # Object 0 covers 300 pixels, object 1 50, object 2 none; all three overlap.
    id_map = np.zeros((20, 20), np.uint32)
    id_map.flat[:300] = 1
    id_map.flat[300:350] = 2
    spheres = np.float32([[0, 0, 0, 1], [0.5, 0, 0, 1], [1, 0, 0, 1]])
    det = viscd.Detector(lambda_=100)
    frame = det.detect(spheres, id_map=id_map)
    np.testing.assert_array_equal(frame.pixels, [300, 50, 0])  # map pixels without a camera
    np.testing.assert_array_equal(frame.state, [1, 0, 0])
    assert frame.pairs.shape == (0, 2)
    both = det.detect(spheres, id_map=id_map, always_active=np.uint8([0, 0, 1]))
    np.testing.assert_array_equal(both.pairs, [[0, 2]])
    # Other integer dtypes convert.
    np.testing.assert_array_equal(det.detect(spheres, id_map=id_map.astype(np.int64)).state, [1, 0, 0])
    # With a camera the counts are scaled by screen area / map area.
    scaled = det.detect(spheres, id_map=id_map, camera=small_camera())
    np.testing.assert_allclose(scaled.pixels, np.float32([300, 50, 0]) * (320 * 240) / 400)


def test_map_size_keywords():
    det = viscd.Detector(map_width=160, map_height=120, report_pixels=True, culling=False)
    frame = det.detect(np.float32([[0, 0, 0, 3]]), camera=small_camera())
    assert frame.pixels[0] > 0
    assert det.config["map_width"] == 160


def test_boxes_with_a_camera():
    boxes = np.float32([[-2, -2, -2, 2, 2, 2], [1, 1, 1, 3, 3, 3], [0, 0, -500, 0.01, 0.01, -499.99]])
    frame = viscd.Detector(lambda_=50).detect(boxes=boxes, camera=small_camera())
    np.testing.assert_array_equal(frame.state, [2, 2, 0])
    np.testing.assert_array_equal(frame.pairs, [[0, 1]])


@pytest.mark.parametrize("bad", [dict(fov_y_deg=180), dict(near=0), dict(far=0.05), dict(up=(0, 0, 1))])
def test_invalid_cameras(bad):
    args = dict(eye=(0, 0, 10), target=(0, 0, 0))
    args.update(bad)
    with pytest.raises(ValueError, match="camera"):
        viscd.Camera(**args)
