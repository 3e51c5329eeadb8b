"""Contact events over a moving scene equal set differences of consecutive brute-force frames."""

import numpy as np

import viscd
from conftest import brute_box_pairs, brute_sphere_pairs, random_boxes, random_spheres


def as_set(pairs):
    return {tuple(p) for p in np.asarray(pairs).tolist()}


def as_sorted(pairs_set):
    return np.array(sorted(pairs_set), np.uint32).reshape(-1, 2)


def test_events_follow_a_moving_scene(backend, rng):
    spheres = random_spheres(rng, 600, extent=25.0)
    velocity = rng.uniform(-0.6, 0.6, (600, 3)).astype(np.float32)
    det = viscd.Detector(backend, contact_events=True)
    previous = set()
    for step in range(12):
        frame = det.detect(spheres)
        current = as_set(brute_sphere_pairs(spheres))
        np.testing.assert_array_equal(frame.began, as_sorted(current - previous))
        np.testing.assert_array_equal(frame.ended, as_sorted(previous - current))
        if step > 0:
            assert len(frame.began) + len(frame.ended) > 0  # the scene does change
        previous = current
        spheres[:, :3] += velocity


def test_events_with_boxes(rng):
    boxes = random_boxes(rng, 300, extent=15.0)
    det = viscd.Detector(contact_events=True)
    first = det.detect(boxes=boxes)
    np.testing.assert_array_equal(first.began, brute_box_pairs(boxes))
    assert first.ended.shape == (0, 2)
    boxes[:, [0, 3]] += 50.0  # everything apart along x? no: all move together; pairs stay
    same = det.detect(boxes=boxes)
    assert same.began.shape == (0, 2) and same.ended.shape == (0, 2)


def test_two_spheres_meet_and_part():
    det = viscd.Detector(contact_events=True)
    seen = []
    for x in [4.0, 2.5, 1.5, 1.0, 2.5, 4.0]:
        f = det.detect(np.float32([[0, 0, 0, 1], [x, 0, 0, 1]]))
        seen.append((f.began.tolist(), f.ended.tolist()))
    assert seen == [([], []), ([], []), ([[0, 1]], []), ([], []), ([], [[0, 1]]), ([], [])]


def test_reset_events_and_events_off():
    s = np.float32([[0, 0, 0, 1], [1, 0, 0, 1]])
    det = viscd.Detector(contact_events=True)
    det.detect(s)
    assert det.detect(s).began.shape == (0, 2)
    det.reset_events()
    np.testing.assert_array_equal(det.detect(s).began, [[0, 1]])
    off = viscd.Detector().detect(s)
    assert off.began.shape == (0, 2) and off.ended.shape == (0, 2)
    det.set_config(contact_events=False)
    assert det.detect(s).began.shape == (0, 2)
