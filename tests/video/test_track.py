"""The tracker on a scene without a model: a reflection half hidden behind the person.

A person filmed from behind, standing in front of the mirror, hides half of their
reflection: the reflection's body circle lies on the person's (its mid-hip within 0.3
of the person's radius, its radius 0.75 of theirs). A fake detector finds both (as
BlazePose does in a few frames of ``bench_agreement.py``'s pair clips) and a fake
landmark model returns the skeleton of the body whose mid-hip is nearest its crop's
centre. Both must be tracked, as two tracks, in every frame.
"""

from __future__ import annotations

import numpy as np

from mirrorgraph.skeletons import BLAZEPOSE
from mirrorgraph.video.blazepose import Detection, Pose
from mirrorgraph.video.nms import pose_nms
from mirrorgraph.video.track import PoseTracker, TrackerOptions

#: A standing body, its left arm raised, mid-hip at the origin, in units of its body
#: circle's radius (y down), its left side at +x (seen from behind).
_PARTS = {"nose": (0, -0.9), "eye": (0.03, -0.92), "ear": (0.07, -0.9), "mouth": (0.02, -0.87),
          "shoulder": (0.2, -0.7), "elbow": (0.26, -0.45), "wrist": (0.28, -0.2),
          "pinky": (0.29, -0.15), "index": (0.28, -0.14), "thumb": (0.26, -0.16),
          "hip": (0.12, 0.0), "knee": (0.12, 0.45), "ankle": (0.12, 0.9), "heel": (0.11, 0.93),
          "big_toe": (0.14, 0.97)}


def _template() -> np.ndarray:
    xy = np.zeros((BLAZEPOSE.num_joints, 2))
    for j, name in enumerate(BLAZEPOSE.joints):
        side = -1.0 if name.startswith("right") else 1.0
        key = next(k for k in _PARTS if k in name)
        x, y = _PARTS[key]
        xy[j] = (side * x if name != "nose" else 0.0, y)
        if name.startswith("left") and key in ("elbow", "wrist", "pinky", "index", "thumb"):
            xy[j] = (0.25 + 0.1 * (key != "elbow"), -0.95 - 0.35 * (key != "elbow"))
    return xy


class _Body:
    def __init__(self, hip, r, mirrored):
        self.hip, self.r = np.asarray(hip, float), float(r)
        t = _template()
        if mirrored:                          # a mirror image: x flipped, labels as seen
            t = t * [-1, 1]
            t = t[BLAZEPOSE.flip]
        self.xy = self.hip + r * t

    def detection(self, score):
        face = self.xy[0] + [[-0.05 * self.r, -0.05 * self.r], [0.05 * self.r, 0.05 * self.r]]
        kp = np.stack([self.hip, self.hip - [0, self.r], self.xy[0], self.hip - [0, 0.7 * self.r]])
        return Detection(box=face.ravel(), keypoints=kp, score=score)

    def pose(self, roi):
        n = BLAZEPOSE.num_joints
        return Pose(xy=self.xy.copy(), visibility=np.ones(n), presence=np.ones(n),
                    aux=np.stack([self.hip, self.hip - [0, self.r]]), score=0.99,
                    roi=np.asarray(roi, float))


class _Scene:
    """A fake model: the detector sees both bodies on the whole frame (nothing on the
    tiles), the landmark model the body nearest its crop's centre."""

    def __init__(self, bodies, size=(1280, 960)):
        self.bodies, self.size = bodies, size

    def detect(self, image, *, gain=1.0, min_score=None):
        if image.shape[1] != self.size[0] or image.shape[0] != self.size[1]:
            return []
        return [b.detection(0.9 - 0.1 * i) for i, b in enumerate(self.bodies)]

    def landmarks(self, image, roi):
        near = min(self.bodies, key=lambda b: np.linalg.norm(b.hip - roi[:2]))
        return near.pose(roi)


def test_a_reflection_half_hidden_behind_the_person_is_tracked():
    person = _Body((600, 560), 240, mirrored=False)
    reflection = _Body((665, 535), 180, mirrored=True)        # 0.75x, behind the person
    # the two are not one person by pose NMS (labels swapped included) ...
    xy = np.stack([person.xy, reflection.xy])
    assert len(pose_nms(xy, np.ones(xy.shape[:2]), flip=BLAZEPOSE.flip)) == 2
    # ... but their body circles overlap as one body's would
    d = np.linalg.norm(person.hip - reflection.hip) / person.r
    assert d < 0.3 and 0.6 < reflection.r / person.r < 1 / 1.2
    scene = _Scene([person, reflection])
    tracker = PoseTracker(scene, TrackerOptions())
    rgb = np.zeros((960, 1280, 3), np.uint8)
    ids = []
    for t in range(12):
        found = tracker.step(rgb, t)
        hips = sorted((round(p.pose.aux[0][0]), p.track_id) for p in found)
        assert [h for h, _ in hips] == [600, 665], f"frame {t}: {hips}"
        ids.append(tuple(i for _, i in hips))
    assert len(set(ids)) == 1 and len(set(ids[0])) == 2


def test_a_track_that_jumps_to_another_body_is_searched_for():
    """The landmark model on the reflection's crop takes the person in front of it from
    frame 3 on (as on the pair clips): the tracker notices the jump, runs the detector
    and holds both again."""
    person = _Body((600, 560), 240, mirrored=False)
    reflection = _Body((665, 535), 180, mirrored=True)
    scene = _Scene([person, reflection])
    tracker = PoseTracker(scene, TrackerOptions())
    rgb = np.zeros((960, 1280, 3), np.uint8)
    counts = []
    for t in range(8):
        if t == 3:                             # the reflection's crop now gives the person
            scene.landmarks = lambda image, roi: person.pose(roi)
        if t == 4:
            del scene.landmarks                # and the model sees right again
        counts.append(len(tracker.step(rgb, t)))
    assert counts[:3] == [2, 2, 2]
    assert counts[-1] == 2 and tracker.stats["detector_runs"] > 1 + 1
