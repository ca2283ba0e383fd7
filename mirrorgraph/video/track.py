"""Every person of every frame, tracked: the person, their reflections, bystanders.

:class:`PoseTracker` runs a pose model (:class:`~mirrorgraph.video.blazepose.BlazePoseModels`
or anything with the same ``detect`` / ``landmarks`` methods) frame by frame, as
MediaPipe's pose graph does for one person, extended to several:

1. every track's crop comes from its landmarks of the frame before; a track ends where
   its crop no longer holds a person or its body circle jumps
   (:attr:`TrackerOptions.max_jump`);
2. the person detector runs only to find people not yet tracked (the cadence of
   :attr:`TrackerOptions.search_every`, :attr:`TrackerOptions.detect_every`,
   :attr:`TrackerOptions.tiles_every`), on the whole frame and on overlapping square
   tiles (:func:`detection_views`), dim views stretched: a reflection is often smaller
   and dimmer than the person. The views' boxes are merged by weighted NMS and by their
   body circles (:func:`same_body`, :attr:`TrackerOptions.merged_ratio`,
   :attr:`PoseTracker.merged`);
3. each tracked person claims the detection whose body circle lies nearest on theirs
   (:meth:`PoseTracker._claimed`); the landmark model runs on every other one's crop
   (retried turned by 180 deg), and a pose filling too little of its crop
   (:func:`extent`) is an object;
4. one skeleton per person: :func:`~mirrorgraph.video.nms.pose_nms` over the frame's
   poses, tracked ones first;
5. a new pose takes the id of a track lost in the last
   :attr:`TrackerOptions.relink_frames` frames whose last box it overlaps, or a new id.

All coordinates are image pixels (x right, y down). Each step in full:
``docs/internals.md``.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from ..skeletons import BLAZEPOSE
from .blazepose import Detection, Pose, weighted_nms
from .nms import oks_matrix, pose_boxes, pose_nms

__all__ = ["TrackerOptions", "PoseTracker", "TrackedPose", "detection_views", "same_body",
           "extent"]


@dataclass(frozen=True)
class TrackerOptions:
    """How :class:`PoseTracker` looks for people.

    Attributes:
        detect_every: run the person detector on the whole frame every
            ``detect_every``-th processed frame while every track is followed (and on
            every frame where a track was lost or nobody is tracked): a person
            entering is found within that many frames.
        tiles_every: run it on the tiles (:func:`detection_views`) every
            ``tiles_every``-th processed frame while every track is followed: small
            people, reflections above all, entering are found within that many
            frames and then followed by their landmarks.
        search_every: while a track lost in the last ``relink_frames`` frames is
            missing, run it on the whole frame and the tiles every ``search_every``-th
            frame.
        flip: also run the detector on the horizontally flipped frame (measured:
            no gain over the tiles on the composited mirror clips; off).
        tiles: run the detector on the tiles at all.
        min_pose_score: the landmark model's person probability below which a crop
            holds nobody (0.5, MediaPipe's).
        min_extent: a new pose whose landmarks (those seen) span less than this
            fraction of its crop's side (the larger side of their box) is no person:
            the crop is 1.25 times the body circle the detector drew around a whole
            body, and a person's landmarks fill about two thirds of it whatever the
            pose, where the landmark model squeezes a skeleton into a part of the
            crop of an object taken for a person. Measured on the Pose2Sim demo
            videos (medians per track): people 0.60-0.69, the false detections (a
            camera rig on the wall, a pile of clothes, scoring 0.55-1.0) 0.15-0.41.
        min_detection_score: the detector's score below which a box is dropped
            (MediaPipe: 0.5; 0.3 here, the landmark model's person probability
            rejecting what is no person: on a composited mirror clip the dim,
            sheared reflection scored 0.3-0.5 in most frames).
        nms_oks: two poses whose object keypoint similarity
            (:func:`~mirrorgraph.video.nms.oks_matrix`, left/right swaps included)
            exceeds this are one person.
        nms_iou: two poses whose keypoint boxes overlap by more than this (intersection
            over union) are one person.
        nms_on_body: a pose with more than this share of its keypoints on a kept
            pose's body (:func:`~mirrorgraph.video.nms.on_body_matrix`; a skeleton the
            landmark model put on a person from a crop turned the wrong way) is that
            person; ``None``: off.
        relink_frames: a new pose takes the id of a track lost at most this many
            frames before, where their boxes overlap.
        max_people: most people tracked in one frame (the best detections first).
        recall_frames: while the tracker holds fewer people than it held in one of
            the last ``recall_frames`` processed frames (a reflection the landmark
            model lost, or whose track slid onto the person and ended there as a
            duplicate), it searches: the detector on the whole frame and the tiles
            every ``search_every``-th frame. A reflection half hidden behind the
            person is separated by the detector in few frames (on
            ``bench_agreement.py``'s pair clips 3-26 % even on every frame), and
            held by the landmark model for a few frames only. Bounded: a clip where
            the count never drops pays nothing, one where it drops pays at most
            ``recall_frames`` frames of searching after the last frame that held
            more. 0: off.
        max_jump: a followed track whose body circle moves by more than this times
            its radius, or whose radius changes by more than a factor ``1 +
            max_jump``, from one frame to the next has gone over to someone else (the
            crop of a reflection half hidden behind the person holds the person too,
            and the landmark model takes them): its pose starts a new track and the
            track is lost (the detector runs, then searches for it). 0: off.
        merged_ratio: a detection that :func:`same_body` merges into a better one
            whose body-circle radius differs from its by more than this factor is
            looked at too (:attr:`PoseTracker.merged`), unless a tracked person
            claims it: one person seen in two views gives two circles of about one
            size, a reflection half hidden behind them a smaller one on theirs
            (measured on the Pose2Sim pair clips of ``bench_agreement.py``: such a
            merge held the reflection in 3-31 of 99 frames). ``inf``: off.
        prefer_detected: where the detector runs on the whole frame and a tracked pose
            claims none of its detections, while a new pose from an unclaimed one is the
            same person by :func:`~mirrorgraph.video.nms.pose_nms` (on its body) with
            neither their joints (object keypoint similarity under ``nms_oks``) nor their
            body circles agreeing, the new pose replaces the tracked one in its track
            (``False``: the tracked pose is kept
            and the new one dropped). Measured on Pose2Sim's Demo_MultiPerson cam03,
            where two people cross: from frame 40 the man's track held a skeleton half
            on the woman beside him (body circle 150-200 px from his), while the
            detector found him whole (score 0.94-0.97) at every run and the landmark
            model on its crop gave his skeleton (score 1.0), dropped as the track's
            duplicate, in 14 runs over 60 frames.
    """

    detect_every: int = 10
    tiles_every: int = 30
    search_every: int = 4
    flip: bool = False
    tiles: bool = True
    min_pose_score: float = 0.5
    min_extent: float = 0.5
    min_detection_score: float = 0.3
    nms_oks: float = 0.5
    nms_iou: float = 0.7
    nms_on_body: float | None = 0.85
    relink_frames: int = 30
    max_people: int = 12
    recall_frames: int = 60
    max_jump: float = 0.3
    merged_ratio: float = 1.2
    prefer_detected: bool = True

    def key(self) -> dict:
        """The options as a dict (for the detection cache's key)."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass
class TrackedPose:
    """A pose in one frame with its track id."""

    track_id: int
    pose: Pose


@dataclass
class _Track:
    track_id: int
    roi: np.ndarray
    box: np.ndarray
    last_frame: int
    lost: bool = False
    circle: np.ndarray | None = None      # (mid-hip x, y, radius) of the last pose


#: Marks a pose of :meth:`PoseTracker.step` that starts a track of its own (never relinked).
_NEW = _Track(track_id=-1, roi=np.zeros(4), box=np.zeros(4), last_frame=-1)


def _circle(pose: Pose) -> np.ndarray:
    """``(3,)`` a pose's body circle: mid-hip x, y and radius (its auxiliary landmarks)."""
    return np.array([*pose.aux[0], np.linalg.norm(pose.aux[1] - pose.aux[0])])


def _same_circle(a: Pose, b: Pose) -> bool:
    """Whether two poses' body circles are one body's: mid-hips within 0.3 times the
    larger radius, radii within a factor 0.6-1.6 (as :meth:`PoseTracker._covered`)."""
    ca, cb = _circle(a), _circle(b)
    return bool(np.linalg.norm(ca[:2] - cb[:2]) < 0.3 * max(ca[2], cb[2])
                and 0.6 < ca[2] / max(cb[2], 1e-9) < 1.6)


def _jumped(circle: np.ndarray | None, pose: Pose, max_jump: float) -> bool:
    """Whether a track's pose moved from its body circle of the frame before by more than
    ``max_jump`` times the larger radius, or changed its radius by more than a factor
    ``1 + max_jump``: no body does that between two frames, a crop whose landmarks
    went over to another person does."""
    if circle is None or max_jump <= 0:
        return False
    now = _circle(pose)
    big, small = max(now[2], circle[2]), max(min(now[2], circle[2]), 1e-9)
    return bool(np.linalg.norm(now[:2] - circle[:2]) > max_jump * big
                or big / small > 1.0 + max_jump)


def detection_views(width: int, height: int, *, flip: bool, tiles: bool
                    ) -> list[tuple[bool, tuple[int, int, int, int]]]:
    """The views the detector runs on: ``(flipped, (x0, y0, x1, y1))`` windows.

    The whole frame, its mirror image (``flip``), and (``tiles``) a grid of squares
    of two thirds of the short side, ``ceil(side / square)`` along each side of the
    frame, spread evenly (6 on a 16:9 frame, overlapping by a sixth across and by
    half down): the detector letterboxes its input to 224 x 224, so a
    tile shows a person at 1.5 to 2.7 times the whole frame's scale. On the
    Pose2Sim demo frames composited into a mirror scene (a person about 290 px
    tall in a 1920 x 1080 frame, at 60 % brightness) the whole frame finds the
    reflection in few frames, squares of the short side in about half, these
    tiles in nearly all.
    """
    views = [(False, (0, 0, width, height))]
    if flip:
        views.append((True, (0, 0, width, height)))
    if tiles:
        s = max(1, round(2 * min(width, height) / 3))

        def starts(n: int) -> list[int]:
            if n <= s:
                return [0]
            k = max(2, int(np.ceil(n / s)))
            return [round(i * (n - s) / (k - 1)) for i in range(k)]
        views.extend((False, (x, y, x + s, y + s)) for y in starts(height) for x in starts(width))
    return views


def _gain(view: np.ndarray, max_gain: float = 3.0) -> float:
    """The factor that stretches a dim view's intensities so that its 99th percentile
    (on every 8th pixel) reaches 255, at most ``max_gain``; 1 for a bright view: a
    reflection half as bright as the room is found as often as the person."""
    top = float(np.percentile(view[::8, ::8], 99))
    if top <= 0 or top >= 242:
        return 1.0
    return min(max_gain, 255.0 / top)


def same_body(keypoints: np.ndarray) -> np.ndarray:
    """``(N, N)`` bool: detections that are one person by their body circles.

    Two detections are one where their mid-hips (the detector's keypoint 0) lie
    within 0.3 times the larger body-circle radius (the distance to keypoint 1) of
    each other and the radii differ by less than a factor 1.6.

    Args:
        keypoints: ``(N, 4, 2)`` the detections' keypoints, image px.
    """
    kp = np.asarray(keypoints, float)
    hip = kp[:, 0]
    r = np.maximum(np.linalg.norm(kp[:, 1] - kp[:, 0], axis=1), 1e-9)
    d = np.linalg.norm(hip[:, None] - hip[None], axis=-1)
    big = np.maximum(r[:, None], r[None])
    ratio = big / np.minimum(r[:, None], r[None])
    return (d < 0.3 * big) & (ratio < 1.6)


def extent(pose: Pose) -> float:
    """The larger side of the box of a pose's landmarks seen (:meth:`Pose.bbox`) over
    the side of the crop they come from (see :attr:`TrackerOptions.min_extent`)."""
    b = pose.bbox()
    return float(max(b[2] - b[0], b[3] - b[1]) / max(pose.roi[2], 1e-9))


def _box_iou(a: np.ndarray, b: np.ndarray) -> float:
    lo, hi = np.maximum(a[:2], b[:2]), np.minimum(a[2:], b[2:])
    inter = float(np.prod(np.clip(hi - lo, 0, None)))
    union = float(np.prod(a[2:] - a[:2]) + np.prod(b[2:] - b[:2])) - inter
    return inter / union if union > 0 else 0.0


class PoseTracker:
    """Tracks every person through a sequence of frames (see the module docstring).

    Args:
        model: has ``detect(rgb) -> list[Detection]`` and
            ``landmarks(rgb, roi) -> Pose``.
        options: :class:`TrackerOptions`.
    """

    #: A box where the landmark model found nobody is not looked at again for this
    #: many frames (background people too small for it, posters, statues): longer than
    #: :attr:`TrackerOptions.detect_every`, so that each run of the detector does not
    #: try them again (three landmark runs each).
    REJECT_FRAMES = 30

    def __init__(self, model, options: TrackerOptions | None = None) -> None:
        self.model = model
        self.options = options or TrackerOptions()
        self._tracks: list[_Track] = []
        self._next_id = 0
        self._count = 0
        self._rejected: list[tuple[np.ndarray, float, int]] = []   # (mid-hip, radius, frame)
        self._held: deque[int] = deque(maxlen=max(1, self.options.recall_frames))  # people a frame
        self.stats = {"detector_runs": 0, "landmark_runs": 0, "search_frames": 0}
        #: the last :meth:`detect_all`'s detections merged into a kept one of another size
        self.merged: list[Detection] = []

    def detect_all(self, rgb: np.ndarray, *, tiles: bool = True) -> list[Detection]:
        """The detector's people over the views of :func:`detection_views` (without the
        tiles where ``tiles`` is false), best first: merged by weighted NMS on their
        boxes, then one a body (:func:`same_body`, the best-scoring kept). Those merged
        into a kept one whose body circle's radius differs from its by more than
        :attr:`TrackerOptions.merged_ratio` are left in :attr:`merged`: a reflection
        half hidden behind the person, smaller, has its body circle on theirs."""
        h, w = rgb.shape[:2]
        boxes, kps, scores = [], [], []
        for flipped, (x0, y0, x1, y1) in detection_views(w, h, flip=self.options.flip,
                                                         tiles=self.options.tiles and tiles):
            view = rgb[y0:y1, x0:x1]
            if flipped:
                view = view[:, ::-1]
            self.stats["detector_runs"] += 1
            for d in self.model.detect(np.ascontiguousarray(view), gain=_gain(view),
                                       min_score=self.options.min_detection_score):
                box, kp = d.box.copy(), d.keypoints.copy()
                if flipped:
                    vw = x1 - x0
                    box[[0, 2]] = vw - box[[2, 0]]
                    kp[:, 0] = vw - kp[:, 0]
                box += [x0, y0, x0, y0]
                kp += [x0, y0]
                boxes.append(box)
                kps.append(kp)
                scores.append(d.score)
        if not scores:
            return []
        b, k, s = weighted_nms(np.array(boxes), np.array(kps), np.array(scores),
                               iou_threshold=0.3)
        same = same_body(k)
        keep: list[int] = []
        self.merged = []
        r = np.linalg.norm(k[:, 1] - k[:, 0], axis=1)
        for i in range(len(s)):                          # best first
            on = [j for j in keep if same[i, j]]
            if not on:
                keep.append(i)
            elif max(r[i], r[on[0]]) > self.options.merged_ratio * max(min(r[i], r[on[0]]), 1e-9):
                self.merged.append(Detection(box=b[i], keypoints=k[i], score=float(s[i])))
        return [Detection(box=b[i], keypoints=k[i], score=float(s[i])) for i in keep]

    def _covered(self, det: Detection, poses: list[Pose], frame: int) -> bool:
        """Whether a detection's mid-hip lies on a pose of ``poses``, at its size, or
        where the landmark model found nobody in the last :attr:`REJECT_FRAMES` frames."""
        hip = det.keypoints[0]
        radius = np.linalg.norm(det.keypoints[1] - det.keypoints[0])
        places = [(p.aux[0], np.linalg.norm(p.aux[1] - p.aux[0])) for p in poses]
        places += [(h, r) for h, r, f in self._rejected if frame - f <= self.REJECT_FRAMES]
        for centre, r in places:
            if np.linalg.norm(centre - hip) < 0.3 * max(r, radius) \
                    and 0.6 < radius / max(r, 1e-9) < 1.6:
                return True
        return False

    @staticmethod
    def _claimed(dets: list[Detection], poses: list[Pose]) -> set[int]:
        """Indices of the detections that are tracked people (:meth:`_claims`)."""
        return set(PoseTracker._claims(dets, poses).values())

    @staticmethod
    def _claims(dets: list[Detection], poses: list[Pose]) -> dict[int, int]:
        """``{pose index: detection index}``, the detections that are tracked people: each pose claims the one
        detection whose body circle lies on its own (as :meth:`_covered`) nearest it
        (mid-hip distance over the larger radius plus the radii's log ratio), each
        detection once. A second detection on a tracked person is looked at: a
        reflection half hidden behind the person has its body circle on theirs
        (measured on the Pose2Sim pair clips of ``bench_agreement.py``: mid-hips
        0.05-0.30 radii apart, radii 0.61-1.17 of the person's), and the person's own
        detection is the nearer one."""
        pairs = []
        for i, det in enumerate(dets):
            hip = det.keypoints[0]
            radius = np.linalg.norm(det.keypoints[1] - det.keypoints[0])
            for j, p in enumerate(poses):
                r = np.linalg.norm(p.aux[1] - p.aux[0])
                d = np.linalg.norm(p.aux[0] - hip) / max(r, radius, 1e-9)
                ratio = radius / max(r, 1e-9)
                if d < 0.3 and 0.6 < ratio < 1.6:
                    pairs.append((d + abs(np.log(ratio)), i, j))
        claims: dict[int, int] = {}
        for _, i, j in sorted(pairs):
            if i not in claims.values() and j not in claims:
                claims[j] = i
        return claims

    def _with_new(self, unique: list[tuple[_Track | None, Pose]], new: list[Pose],
                  supported: set[int]) -> list[tuple[_Track | None, Pose]]:
        """The frame's tracked poses ``unique`` with the ``new`` ones (from detections no
        tracked pose claimed), one each (:meth:`_one_each`, the tracked ones first). A
        tracked pose that claimed no detection (not in ``supported``, indices into
        ``unique``) is replaced in its track by a new pose whose body circle lies
        elsewhere (not as :meth:`_covered`), whose joints it does not match (object
        keypoint similarity under :attr:`TrackerOptions.nms_oks`) and of which it is a
        duplicate by pose NMS all the same (on its body, the new one first), where the
        new pose duplicates no other
        (:attr:`TrackerOptions.prefer_detected`): that track's crop slid off its person
        into a skeleton half on a neighbour, where the detector, run on the whole frame,
        finds the person whole elsewhere (cam03 of Demo_MultiPerson, frame 48: circles
        0.35 radii apart, OKS 0.11, 94 % of the track's keypoints on the new body).
        Where the circles or the joints agree the tracked pose stays (a reflection the
        detector does not find, whose new pose from another box is no better; a person
        cut by the image's edge whose detector box is shifted: cam02, frame 80, circles
        0.34 radii apart, OKS 0.55)."""
        every = [p for _, p in unique] + new
        out = unique + [(None, every[i]) for i in self._one_each(every).tolist()
                        if i >= len(unique)]
        if not self.options.prefer_detected:
            return out
        for i in range(len(unique)):
            if i in supported:
                continue
            for pose in new:
                if any(q is pose for j, (tr, q) in enumerate(out) if j != i and tr is not None
                       and j < len(unique)):
                    continue                            # already given to a track
                if _same_circle(pose, unique[i][1]) or self._oks(pose, unique[i][1]) \
                        >= self.options.nms_oks or len(self._one_each([pose, unique[i][1]])) != 1:
                    continue
                others = [q for j, (_, q) in enumerate(out) if j != i and q is not pose]
                if len(self._one_each(others + [pose])) <= len(others):
                    continue                            # someone else's duplicate
                out[i] = (unique[i][0], pose)           # the track follows the detected body
                out = [(tr, q) for j, (tr, q) in enumerate(out)
                       if j < len(unique) or q is not pose]
                break
        return out


    def _one_each(self, poses: list[Pose]) -> np.ndarray:
        """Indices of ``poses`` kept by :func:`~mirrorgraph.video.nms.pose_nms` (the
        order is the preference)."""
        if len(poses) < 2:
            return np.arange(len(poses))
        return pose_nms(np.stack([p.xy for p in poses]),
                        np.stack([p.visibility for p in poses]),
                        oks_threshold=self.options.nms_oks, iou_threshold=self.options.nms_iou,
                        on_body=self.options.nms_on_body,
                        flip=BLAZEPOSE.flip if len(poses[0].xy) == BLAZEPOSE.num_joints
                        else None)

    @staticmethod
    def _oks(a: Pose, b: Pose) -> float:
        """Object keypoint similarity of two poses (:func:`~mirrorgraph.video.nms.oks_matrix`,
        left/right swaps included)."""
        xy, vis = np.stack([a.xy, b.xy]), np.stack([a.visibility, b.visibility])
        flip = BLAZEPOSE.flip if len(a.xy) == BLAZEPOSE.num_joints else None
        return float(oks_matrix(xy, vis, pose_boxes(xy, vis, 0.5), flip=flip)[0, 1])

    def _converged(self, poses: list[Pose]) -> set[int]:
        """Indices of the followed ``poses`` (in the order of preference) kept: a pose that
        :meth:`_one_each` drops is dropped where its body circle also lies on a kept
        one's (as :meth:`_covered`: two tracks that converged onto one person follow
        one body). Two people one in front of the other have skeletons that pose NMS
        may call one (measured on Pose2Sim's Demo_MultiPerson cam03, the woman drawn
        over the man: object keypoint similarity 0.52, 73-88 % of her keypoints on his
        body) while their body circles lie 0.36-0.55 radii apart, radii 1.3-1.4 times
        one another's."""
        keep = set(self._one_each(poses).tolist())
        for i in range(len(poses)):
            if i not in keep and not any(_same_circle(poses[i], poses[k]) for k in keep):
                keep.add(i)
        return keep

    def _searching(self, tracked: int) -> bool:
        """Whether fewer people are tracked than in one of the last
        :attr:`TrackerOptions.recall_frames` frames."""
        return self.options.recall_frames > 0 and bool(self._held) and max(self._held) > tracked

    def _detector_due(self, lost_now: bool, tracked: int, frame: int,
                      searching: bool = False) -> tuple[bool, bool]:
        """``(run the detector, on the tiles too)`` this frame (the module docstring, 2)."""
        o, n = self.options, self._count
        if lost_now or tracked == 0:
            return True, True
        missing = any(t.lost and frame - t.last_frame <= o.relink_frames for t in self._tracks)
        if (missing or searching) and n % o.search_every == 0:
            return True, True
        tiles = n % o.tiles_every == 0
        return tiles or n % o.detect_every == 0, tiles

    def step(self, rgb: np.ndarray, frame: int) -> list[TrackedPose]:
        """Every person in one ``(H, W, 3)`` uint8 RGB frame, with track ids."""
        o = self.options
        followed: list[tuple[_Track, Pose]] = []
        jumped: list[Pose] = []
        lost_now = False
        for tr in sorted(self._tracks, key=lambda t: t.track_id):      # the oldest first
            if tr.lost:
                continue
            self.stats["landmark_runs"] += 1
            pose = self.model.landmarks(rgb, tr.roi)
            if pose.score < o.min_pose_score:
                tr.lost, lost_now = True, True
            elif _jumped(tr.circle, pose, o.max_jump):
                # the crop's landmarks went over to someone else (a reflection's crop
                # onto the person in front of it): that pose is a new track's, the
                # track's own subject is lost and searched for
                tr.lost, lost_now = True, True
                jumped.append(pose)
            else:
                followed.append((tr, pose))
        # one person followed twice (two tracks converged): the track whose body circle
        # moved least from its last goes on (the other slid over), the older first at a tie
        moved = [0.0 if tr.circle is None else float(
            np.linalg.norm(_circle(p)[:2] - tr.circle[:2]) / max(tr.circle[2], 1e-9))
            for tr, p in followed]
        order = sorted(range(len(followed)), key=lambda i: moved[i])
        keep = {order[i] for i in self._converged([followed[i][1] for i in order])}
        for i, (tr, _) in enumerate(followed):
            if i not in keep:
                tr.lost = True
        unique: list[tuple[_Track | None, Pose]] = [followed[i] for i in sorted(keep)]
        if jumped:
            every = [p for _, p in unique] + jumped
            unique += [(_NEW, every[i]) for i in self._one_each(every).tolist()
                       if i >= len(unique)]
        searching = self._searching(len(unique))
        self.stats["search_frames"] += searching
        run, tiles = self._detector_due(lost_now, len(unique), frame, searching)
        if run:
            new: list[Pose] = []
            dets = self.detect_all(rgb, tiles=tiles)[:o.max_people]
            first = len(dets)
            dets += self.merged[:o.max_people]        # bodies behind another one's
            claims = self._claims(dets, [p for _, p in unique])
            claimed = set(claims.values())
            for i, det in enumerate(dets):
                if len(unique) + len(new) >= o.max_people or i in claimed or \
                        self._covered(det, new if i < first else [], frame):
                    continue
                pose = self._landmarks_of(rgb, det)
                if pose.score < o.min_pose_score or extent(pose) < o.min_extent:
                    self._rejected.append((det.keypoints[0], float(np.linalg.norm(
                        det.keypoints[1] - det.keypoints[0])), frame))
                    continue
                new.append(pose)
            if new:
                unique = self._with_new(unique, new, set(claims))
        self._count += 1
        self._held.append(len(unique))
        out = []
        for tr, pose in unique:
            if tr is None:
                tr = self._relink(pose, frame)
            elif tr is _NEW:
                tr = self._new_track(pose)
            tr.roi, tr.box, tr.last_frame, tr.lost = pose.next_roi, pose.bbox(), frame, False
            tr.circle = _circle(pose)
            out.append(TrackedPose(tr.track_id, pose))
        self._tracks = [t for t in self._tracks
                        if not t.lost or frame - t.last_frame <= o.relink_frames]
        self._rejected = [r for r in self._rejected if frame - r[2] <= self.REJECT_FRAMES]
        return out

    def _landmarks_of(self, rgb: np.ndarray, det: Detection) -> Pose:
        """The landmarks in a new detection's crop; where the landmark model sees nobody
        there, the same crop turned upright, then turned by 180 deg.

        The detector's rotation comes from two of its keypoints (mid-hip to the
        body-circle point); on a small, dim reflection it is often upside down
        (measured on a composited mirror clip: 26 of 30 frames), and the landmark
        model then finds nobody in a crop that holds the person.
        """
        roi = det.roi
        best = None
        for rot in (roi[3], 0.0, roi[3] + np.pi):
            self.stats["landmark_runs"] += 1
            cand = np.array([roi[0], roi[1], roi[2], (rot + np.pi) % (2 * np.pi) - np.pi])
            pose = self.model.landmarks(rgb, cand)
            if best is None or pose.score > best.score:
                best = pose
            if pose.score >= self.options.min_pose_score:
                break
        return best

    def _relink(self, pose: Pose, frame: int) -> _Track:
        box = pose.bbox()
        best, best_iou = None, 0.3
        for t in self._tracks:
            if t.lost and frame - t.last_frame <= self.options.relink_frames:
                iou = _box_iou(box, t.box)
                if iou > best_iou:
                    best, best_iou = t, iou
        if best is not None:
            return best
        return self._new_track(pose)

    def _new_track(self, pose: Pose) -> _Track:
        tr = _Track(track_id=self._next_id, roi=pose.roi, box=pose.bbox(), last_frame=-1)
        self._next_id += 1
        self._tracks.append(tr)
        return tr
