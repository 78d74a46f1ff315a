"""The simulated hand (psvs.calibrate.handheld) and the assistant's words, without rendering: the path's
poses against what it promises, and the hint for a planted coverage and pose."""
import itertools
import math

import numpy as np
import pytest

from psvs.calibrate.capture import ALL_BINS, CaptureAssistant, CaptureParams, CardPose
from psvs.calibrate.handheld import SETTLE_FRAMES, HandParams, hand_path
from psvs.io.params import load_rig
from psvs.optics.project import project_points
from psvs.simulate.textures import CircleGrid

CARD = CircleGrid(4, 6, 14.0, 7.0)


@pytest.mark.parametrize("seed", [0, 3])
def test_hand_path_keeps_its_promises(seed):
    """Holds at 400-900 mm, every disc of both views inside the image (a pose pushed out: some outside the
    left view's image); moving frames whose exposures join up (the path is continuous: the last pose of one
    frame's exposure is one sample step from the next frame's first); tilts of 20-32 deg or flat (< 6 deg)."""
    rig = load_rig("misaligned")
    hand = HandParams(hold_frames=2, move_frames=2, blur_samples=3, out_every=4, settle_every=3)
    plan = hand_path(rig, CARD, 8, seed=seed, hand=hand)
    kinds = [f.kind for f in plan]
    assert kinds.count("out") == 2 * 2 and kinds.count("still") == 6 * 2
    assert kinds.count("moving") == 7 * 2 + 2 * SETTLE_FRAMES       # the 3rd and 6th holds settle
    local = np.column_stack([CARD.centres_mm(), np.zeros(24)])
    w, h = rig.camera.image_size_px
    for f in plan:
        p = f.poses[0]
        if f.kind == "moving":
            assert len(f.poses) == 3
            continue
        assert 400.0 <= p.position_mm[2] <= 900.0
        n = -p.rotation[:, 2]
        turn = math.degrees(math.acos(-n[2]))
        assert turn < 6.0 or 19.0 < turn < 35.0
        inside = []
        for view in ("left", "right"):
            uv, ok = project_points(p.to_world(local), rig, view)
            inside.append(ok & (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1))
        assert (f.kind == "still") == bool(inside[0].all() and inside[1].all())
    poses = [p for f in plan for p in f.poses]
    steps = [np.linalg.norm(b.position_mm - a.position_mm) for a, b in itertools.pairwise(poses)]
    assert max(steps) < 200.0                                         # no jump: one move at most in a step
    holds = [f for f in plan if f.kind != "moving"]
    assert all(len(f.poses) == 1 for f in holds) and len({id(f.poses[0]) for f in holds}) == 8


def _pose(z_mm, centres=((400.0, 240.0), (150.0, 240.0))):
    """A card at depth z whose centre lands at ``centres`` (left view, right view; px): here the centre and
    the left cells of the middle row (640 x 480 px: columns split at 213 and 427, rows at 160 and 320)."""
    return CardPose(np.eye(4), z_mm, 0.0, 0.0, {"left": centres[0], "right": centres[1]})


def test_hints_in_a_card_holders_words():
    """With a planted coverage: the first missing depth (closer or farther, with the range), then the nearest
    missing cell of the field (its direction from where the card's centres are now, as the image shows it),
    then the tilt; a new pose when only the count is short; 'enough' when complete."""
    a = CaptureAssistant(CARD, load_rig("clear"), CaptureParams(views=4, near_mm=400.0, far_mm=900.0))
    a.covered = {b: 1 for b in ALL_BINS}
    at = _pose(800.0)                                  # centres in the middle row: centre and left cells
    a.covered["depth:near"] = 0
    assert a._advice(at) == "closer (400-567 mm)"
    a.covered["depth:near"], a.covered["depth:far"] = 1, 0
    assert a._advice(_pose(450.0)) == "farther (733-900 mm)"
    a.covered["depth:far"], a.covered["field:top-right"], a.covered["field:bottom-left"] = 1, 0, 0
    assert a._advice(at) == "move down"                 # bottom-left: one row down from the left cell
    a.covered["field:bottom-left"] = 1
    assert a._advice(at) == "move right and up"
    a.covered["field:top-right"], a.covered["tilt:up"] = 1, 0
    assert a._advice(at) == "tilt up"
    a.covered["tilt:up"], a.covered["tilt:flat"] = 1, 0
    assert a._advice(at) == "hold it flat"
    a.covered["tilt:flat"] = 1
    assert a._advice(at) == "a new pose: another distance, tilt or place"
    assert a.describe_missing() == "4 more view(s)"
    a.saved = [at] * 4
    assert a.complete and a._advice(at) == "enough to calibrate" and a.describe_missing() == ""


def test_a_still_frame_of_the_video_is_the_renderers_image_fall_off_included():
    """On a lens that dims its corners (relative illumination 1 - rho^2), a frame where the card is held still
    is exactly what the renderer gives for that pose (the two views split by the plate and dimmed by the
    lens, then exposed with the frame's noise): the video's composition is the renderer's, not a copy without
    the fall-off. Dark corners are planted: the frame's corner is at most 0.9 of the flat lens's there."""
    from psvs.calibrate.handheld import card_scene, render_hand_video
    from psvs.optics.illumination import illumination_map
    from psvs.simulate.render import render
    from psvs.simulate.sensor import IDEAL
    rig = load_rig("misaligned").replace(relative_illumination=(-1.0, 0.0))
    assert illumination_map(rig.camera)[0, 0] < 0.9
    hand = HandParams(hold_frames=1, move_frames=1, blur_samples=2, out_every=99, settle_every=99)
    plan = hand_path(rig, CARD, 2, seed=1, hand=hand)
    frames = list(render_hand_video(rig, CARD, plan, seed=7, sensor=IDEAL))
    assert len(frames) == len(plan)
    still = [k for k, f in enumerate(plan) if f.kind == "still"]
    assert still
    for k in still:
        want = render(card_scene(CARD, plan[k].poses[0]), rig, supersample=1, sensor=IDEAL, seed=7 + k)
        np.testing.assert_array_equal(frames[k], want.image)
    flat = render(card_scene(CARD, plan[still[0]].poses[0]), load_rig("misaligned"), supersample=1, sensor=IDEAL)
    corner = (slice(0, 20), slice(0, 20))
    assert frames[still[0]][corner].mean() <= 0.9 * flat.image[corner].mean()
