"""Options of the factor-graph refinement (:func:`mirrorgraph.pipelines.solve.refine_mirror`).

Every prior's weight is a standard deviation ``sigma`` (weight ``1 / sigma^2`` in the
whitened least-squares objective). Lengths are relative to the subject's height ``h`` in
the graph's length unit: the given ``subject_height`` (metres), or without it the height
implied by the initial triangulation's median bone lengths and Winter's proportions (in
units of the mirror distance), so the defaults hold whatever the gauge.

The defaults' evidence: ``bench/RESULTS_priors.md`` (which bones enter,
``bone_bias_limit``: RMS error over the bound per setting); the protocol and the
reasoning behind every default: ``docs/internals.md``.

The two acceleration priors (``smoothness_sigma``, ``joints_smoothness_sigma``) are
stated at :data:`REFERENCE_FPS`, a fraction of ``h`` per frame^2 of a 30 fps video
(x 900 = ``h`` per s^2): :meth:`PriorOptions.at_frame_rate` turns them into the video's
frame interval, once, where a pipeline meets its frame rate; the graph, the completion
and live's joint filter take them per frame (their frame gaps in frame numbers).

The settings are grouped by concern, one class each (:class:`PriorOptions`,
:class:`ScheduleOptions`, :class:`SolverOptions`, :class:`GaugeOptions`, each setting in
exactly one of them); :class:`RefineOptions`, the one options object of the solve driver,
is all of them together (as GTSAM's ``LevenbergMarquardtParams`` extends
``NonlinearOptimizerParams``): ``RefineOptions(bone_sigma=0.02, max_iterations=10)``, or
:meth:`RefineOptions.from_groups` from the groups, and back with
:attr:`RefineOptions.priors` etc.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Literal, Self, get_args

from ..anthropometry import height_problem
from ..errors import InputError

#: Robust kernels of the reprojection factors (:func:`mirrorgraph.factors.reprojection.robust_pixel_noise`).
Kernel = Literal["geman_mcclure", "huber", "cauchy", "tukey"]
KERNELS: tuple[str, ...] = get_args(Kernel)

#: How the joints pass measures the bones the calibration graph left out
#: (``PriorOptions.joints_bone_lengths``).
BoneLengths = Literal["moments", "integrated"]
BONE_LENGTHS: tuple[str, ...] = get_args(BoneLengths)

#: The ways a subject height becomes a length (``GaugeOptions.scale_from``).
ScaleFrom = Literal["stature", "limbs"]
SCALE_FROM: tuple[str, ...] = get_args(ScaleFrom)

__all__ = ["BONE_LENGTHS", "BoneLengths", "GaugeOptions", "KERNELS", "one_subject_height", "Kernel", "PriorOptions", "RefineOptions", "SCALE_FROM",
           "FocalOptions", "REFERENCE_FPS", "ScaleFrom", "ScheduleOptions", "SolverOptions"]

#: The frame rate, Hz, at which the acceleration priors (``smoothness_sigma``,
#: ``joints_smoothness_sigma``) are stated: a fraction of ``h`` per frame^2 at this rate
#: (x ``REFERENCE_FPS^2`` = 900: ``h`` per s^2), whatever the video's
#: (:meth:`PriorOptions.at_frame_rate`).
REFERENCE_FPS = 30.0


@dataclass(frozen=True, kw_only=True)
class FocalOptions:
    """How the intrinsics of a camera given without them are estimated.

    Which cameras: :attr:`mirrorgraph.graph.rig.Camera.estimate_focal` (the front ends
    set it for a camera without intrinsics: ``calibrate`` without ``--intrinsics`` and
    without ``--fov``, a rig camera without ``intrinsics``). These options say how.

    What determines the focal length of one camera and a mirror: not the images'
    epipolar geometry (``F ~ [K n]x`` fixes the epipole, the image of the normal, for
    any focal length), but the body: bones keep their length from pose to pose, and a
    wrong focal length stretches the reconstruction along the line of sight against
    across it (``bench/RESULTS_focal.md``). So the bones decide it, and where their
    lengths are measured with a curvature bias (joints whose rays meet at a small
    angle, :func:`~mirrorgraph.graph.builder.bone_curvature_bias`) that bias is a
    stretch too: it biases the focal length, by +19 % on a far scene at 4 px with every
    bone in every frame. ``bone_bias_limit`` keeps the bones whose bias is small.

    Attributes:
        principal_point: ``True`` (``--principal-point free``): the principal point's
            prior is loose (:data:`~mirrorgraph.graph.builder.PRINCIPAL_POINT_PRIOR`,
            5 % of the image width), so that the people decide it, which they do
            poorly; ``False`` (default): its prior is the spread of real cameras,
            ``principal_point_rel_sigma``. Either way it is a variable of the graph
            and its uncertainty is in every reported standard deviation.
        principal_point_rel_sigma: the standard deviation of each coordinate of the
            principal point about the image centre, fraction of the image's larger
            side: 1 % (19 px at 1920 px). Phones' calibrated principal points lie a
            few pixels to about 1.5 % of the width off the centre (an iPhone X's ARKit
            intrinsics at 1920x1440: 3.8 and 1.7 px; another phone's at the same size:
            29 and 3 px; README, Unknown intrinsics).
        search_fov_deg: the focal length's initial search (one camera and its mirrors,
            :func:`~mirrorgraph.graph.stages.focal_search`) spans these horizontal
            fields of view, degrees.
        search_steps: candidate focal lengths of that search (log-spaced; the
            geometric midpoints beside the best are solved too, and a parabola through
            the best of these and its neighbours refines it).
        search_frames: frames (spread over the video) of each candidate's solve.
        bone_bias_limit: the calibration graph's bone rule (``RefineOptions.
            bone_bias_limit``) where a focal length is estimated: 1 (a bone's bias under
            one bone sigma) against 0.3 for known intrinsics. On 12 wide scenes (4 px,
            1000 frames, started at the true focal length) 0.3 left no bone in five
            scenes, 1 in three, with a median focal error of 0.6 % either way where
            bones were left.
        prior_rel_sigma: a weak Gaussian prior on the focal length about the front
            end's guess (:attr:`~mirrorgraph.graph.rig.Camera.focal_prior`), this
            fraction of it: where the data do not determine the focal length the
            guess is kept (and the warning says so), and the graph stays solvable;
            where they do (a standard deviation of a few per cent) it moves the
            estimate by a fraction of a per cent at most.
        anthropometry: keep the anthropometric ratios (``RefineOptions.
            use_anthropometry``) where a focal length is estimated. Off: Winter's
            population proportions alone "determine" the focal length of a person who
            holds one pose (its bound 3.9 % on a favourable 1000-frame scene, the
            symmetry alone 19 %, neither infinite), a bias for any individual, while with
            motion they add nothing (0.455 % with them, 0.457 % without).
        undetermined_rel_std: a focal length whose standard deviation (the larger of
            the marginal and the time-robust figure) exceeds this fraction of it is
            reported as poorly determined by the data (a warning): too little depth
            change, a person who hardly moves, bones measured with a curvature bias.
        fallback_rel_std: above this fraction the data do not determine it at all: the
            guess is kept (the rig solved again with it held) and a warning says so.
            Between the two the estimate stays (on a wide scene whose estimate has a
            std of 6.5 % its error is 6.5 %, the guess's 30 %). Above it the estimate
            stays too (the posterior under the weak prior), with its large standard
            deviation in every figure and a warning.
        guess_rel_sigma: a field-of-view guess the user gives (``--fov DEG``) is the
            centre of the focal length's prior with this relative standard deviation
            (a phone's video mode crops and stabilises: its field of view is not the
            specification's): the focal length stays a variable of the graph, so
            that the guess's own spread is in every standard deviation.
        lines: where the input is a video (``calibrate clip.mp4``, or keypoints with
            ``CalibrateOptions.video``) and the focal length is estimated, the scene's
            straight lines are a second witness (:mod:`mirrorgraph.initial.vanishing`:
            the vanishing points of orthogonal directions, on the median background of
            ``lines_frames`` frames): their estimate, with its bootstrap standard
            deviation, joins the guess's prior on the focal length in the graph (the
            two Gaussians are one factor, :func:`~mirrorgraph.graph.priors.add_focal_prior`),
            and each cue is reported apart (``intrinsics.estimated.focal_sources``).
            On the Pose2Sim demo's 8 camera clips (a lab) within 2.3 % of Qualisys
            (``bench/RESULTS_lines.md``). ``False`` (``--no-lines``): the person alone.
        lines_frames: frames sampled over the video for the lines' median background.
        bias_replicates: noisy replicates of the focal length's bias
            (:func:`~mirrorgraph.graph.solve.focal_bias`: the calibration graph's joints
            re-imaged and solved again, once without noise and this many times with the
            data's pixel noise; the squared bias, never under its estimate's own
            sampling variance, is added to the variance of a determined focal length).
            Each is one solve of up to :data:`~mirrorgraph.graph.solve.FOCAL_BIAS_FRAMES`
            frames (the fixture scene_901, 1000 frames: 4.1-4.7 s of CPU without,
            6.3-6.7 s with one). One replicate: on 20 scenes with 6 draws each
            (``bench/RESULTS_focal_bias.md``) |error| / std beyond 3 in 1 % of the
            draws, the median 0.97; more replicates shrink that floor and the std with
            it (3 replicates: 2 % beyond 3, twice the solves). 0: no bias term (the
            data's std alone: 25 % of those scenes beyond 3 std).
    """

    principal_point: bool = False
    principal_point_rel_sigma: float = 0.01
    search_fov_deg: tuple[float, float] = (20.0, 120.0)
    search_steps: int = 9
    search_frames: int = 150
    bone_bias_limit: float | None = 1.0
    prior_rel_sigma: float = 0.5
    anthropometry: bool = False
    undetermined_rel_std: float = 0.05
    fallback_rel_std: float = 0.2
    guess_rel_sigma: float = 0.1
    lines: bool = True
    lines_frames: int = 31
    bias_replicates: int = 1

    def __post_init__(self) -> None:
        if isinstance(self.bias_replicates, bool) or not isinstance(self.bias_replicates, int) \
                or self.bias_replicates < 0:
            raise InputError(f"must be a number of replicates >= 0, got {self.bias_replicates!r}",
                             field="bias_replicates")
        if isinstance(self.lines_frames, bool) or not isinstance(self.lines_frames, int) \
                or self.lines_frames < 1:
            raise InputError(f"must be a positive number of frames, got {self.lines_frames!r}",
                             field="lines_frames")


@dataclass(frozen=True, kw_only=True)
class PriorOptions:
    """The body priors of the graph: which are on and their weights.

    Each prior is a factor module of :mod:`mirrorgraph.factors` (``bone_length``,
    ``symmetry``, ``anthropometry``, ``hip``, ``smoothness``); its weight is a standard
    deviation in units of the subject's height ``h`` (see the module docstring for how
    the defaults were measured).

    Attributes:
        bone_sigma: ``L_var``, a bone's length about its constant value, fraction of ``h``.
        bone_bias_limit: ``c``: a bone's factor in a frame is left out of the
            calibration graph where its length, measured from the joints' rays, is
            biased by more than ``c`` bone sigmas by the noise across the bone
            (:func:`~mirrorgraph.graph.builder.bone_curvature_bias`, second order:
            joints whose rays meet at a small angle have centimetres of depth
            noise); ``None``: every bone in every frame. The joints pass keeps
            every bone (the mirror is held there).
        symmetry_sigma: ``L_sym``, left minus right length, fraction of ``h``.
        anthropometry_sigma: ``L_anth``, the ratio length / femur about Winter's (absolute).
        hip_sigma: ``L_hip``, the normalised cross product (~ sine of the hip angle).
        smoothness_sigma: ``L_smooth``, acceleration, fraction of ``h`` per frame^2 at
            :data:`REFERENCE_FPS` (x 900 = ``h``/s^2; 0.8: 720 ``h``/s^2).
        smoothness_max_gap: longest frame step bridged by a smoothness factor, frames
            of the video.
        joints_smoothness_sigma: after the mirror is found, the 3D joints are solved
            once more with the mirror and the bone lengths held and this (tighter)
            smoothness, fraction of ``h`` per frame^2 at :data:`REFERENCE_FPS` (x 900 =
            ``h``/s^2: 0.01 is 9 ``h``/s^2, 15 m/s^2 for 1.7 m); ``None`` skips that pass (the
            joints are then the calibration's). The mirror wants a loose prior (a
            tight one biases it), the motion a tight one (it halves the joints'
            error: PA-MPJPE 15-20 -> 9-11 mm on protocol and CMU scenes, mirror
            unchanged, +0.4 s per 1000 frames): the two passes give each its own.
            Videos solved in chunks (longer than ``max_graph_frames``) get it
            chunk by chunk with the final mirror. The same sigma sets the joints' std
            (:mod:`~.joints_uncertainty`), the completed joints' smoothing and live's
            joint filter (:class:`mirrorgraph.live.joint_filter.JointFilter`), each at
            the video's frame interval (:meth:`at_frame_rate`: a 60 fps video's graph
            gets 0.0025 per frame^2, the same 9 ``h``/s^2; CMU take 01_01 at 60 fps:
            PA-MPJPE 20.1 -> 15.4 mm against the prior per frame number,
            ``bench/RESULTS_smoothness.md``). At 30 fps, 0.005
            lowers the PA-MPJPE on every kind (CMU 18.3 -> 16.6 mm, iid 15.7 -> 13.6,
            independent fixtures 20.3 -> 17.6; medians) but the std shrinks faster than
            the error: the realistic detector's scenes with error / std p99 over 3 go
            from 3 to 5 of 12, CMU's wrists' worst p99 from 2.97 to 3.36; at 0.0025 the
            wrists lose 13 % (``bench/RESULTS_smoothness.md``).
        torso_sigma: the joints pass holds the torso nearly rigid: the distances
            between the shoulders and the hips that no bone holds (the two sides and
            the two diagonals, :mod:`mirrorgraph.factors.torso`), with this standard
            deviation, fraction of ``h`` (3.4 cm for 1.7 m: above the 0.5-0.7 cm the
            trunk's bending and the shoulder girdle give them in motion capture).
            Each distance is its median over the calibration's joints in the frames
            where their rays fix its length (its curvature bias under
            ``bone_bias_limit``), or where it has too few such frames over the joints
            pass solved first without it (:func:`~mirrorgraph.graph.stages.joints_pass`).
            It ties a shoulder whose rays meet at a few degrees to the hips, whose depth
            the legs hold; with ``joints_bone_lengths="integrated"`` it takes the median
            calibrate PA-MPJPE of low-parallax scenes from 32.8 to 26.4 mm and the
            realistic detector's worst scene's share of joints more than 1 m off from
            99.8 to 0 % (``bench/RESULTS_joints_lengths_torso.md``); with lengths
            28-50 % short it makes a scene worse (``bench/RESULTS_low_parallax_depth.md``),
            hence the integrated lengths beside it. ``None``: no torso term.
        joints_bone_lengths: how the joints pass measures the bones the calibration
            graph left out, on the joints triangulated with the solved mirror:
            ``"integrated"`` the likelihood with each frame's bone direction integrated
            out, left and right one length
            (:func:`~mirrorgraph.graph.bones.integrated_bone_lengths`: right where rays
            meet at a few degrees, where a moment estimate takes a biased depth as
            length), or ``"moments"`` the mean of ``|d|^2 - tr S``
            (:func:`~mirrorgraph.graph.bones.debiased_bone_lengths`: a fraction of the
            cost; without the torso term the integrated lengths slide more joints in
            depth on some scenes, ``bench/RESULTS_joints_bonelengths.md``).
        use_bone_length, use_symmetry, use_anthropometry, use_hip, use_smoothness:
            switch each prior of the calibration graph (the hip prior also needs a
            mid-hip joint; the subject-height gauge needs the bone lengths, so it
            keeps them on; the smoothness is off: see the module docstring, the
            joints pass has its own).
    """

    bone_sigma: float = 0.01
    bone_bias_limit: float | None = 0.3
    symmetry_sigma: float = 0.005
    anthropometry_sigma: float = 0.05
    hip_sigma: float = 0.1
    smoothness_sigma: float = 0.8
    smoothness_max_gap: int = 4
    joints_smoothness_sigma: float | None = 0.01
    torso_sigma: float | None = 0.02
    joints_bone_lengths: BoneLengths = "integrated"
    use_bone_length: bool = True
    use_symmetry: bool = True
    use_anthropometry: bool = True
    use_hip: bool = True
    use_smoothness: bool = False

    def __post_init__(self) -> None:
        if self.joints_bone_lengths not in BONE_LENGTHS:
            raise InputError(f"must be one of {', '.join(BONE_LENGTHS)}, got "
                             f"{self.joints_bone_lengths!r}", field="joints_bone_lengths")

    def at_frame_rate(self, fps: float) -> Self:
        """These options with the acceleration priors at a video's frame interval.

        ``smoothness_sigma`` and ``joints_smoothness_sigma`` are stated per frame^2 at
        :data:`REFERENCE_FPS`; a second difference of a smooth motion scales as the
        frame interval squared, so at ``fps`` each is multiplied by
        ``(REFERENCE_FPS / fps)^2``: the same acceleration in ``h``/s^2 whatever the
        rate. The result is what the graph reads (per frame number; a gap of ``g``
        frames is ``g`` frame intervals of the video); convert once, where the pipeline
        resolves its frame rate.

        Args:
            fps: the video's frame rate, Hz (positive).

        Returns:
            A copy of the same class; ``self`` at :data:`REFERENCE_FPS`.

        Raises:
            InputError: ``fps`` not a positive finite number, field ``fps``.

        Example:
            >>> RefineOptions().at_frame_rate(60.0).joints_smoothness_sigma
            0.0025
        """
        if (isinstance(fps, bool) or not isinstance(fps, (int, float))
                or not (math.isfinite(fps) and fps > 0)):
            raise InputError(f"frame rate must be a positive number, got {fps!r}", field="fps")
        k = (REFERENCE_FPS / float(fps)) ** 2
        if k == 1.0:
            return self
        j = self.joints_smoothness_sigma
        return replace(self, smoothness_sigma=self.smoothness_sigma * k,
                       joints_smoothness_sigma=None if j is None else j * k)


@dataclass(frozen=True, kw_only=True)
class ScheduleOptions:
    """The robust schedule: the noise model, the kernels and the outlier passes.

    The first solve hunts outliers with a robust kernel on the reprojection terms, the
    ones after it carry the body priors with the final kernel (:mod:`.stages`); pairs
    that the data cannot hold (rays meeting at a small angle, residuals over the
    threshold) are left out by the rules here.

    Attributes:
        pixel_sigma: standard deviation of a keypoint coordinate, px (the
            paper's simulated detector noise is 4 px). ``lambda_repro = 1 / sigma^2``.
        robust_kernel: ``"geman_mcclure"`` (the paper), ``"huber"``, ``"cauchy"``,
            ``"tukey"`` or ``None``.
        kernel_scale_px: the kernel's scale in the first (reprojection-only,
            outlier-hunting) solve, px of residual norm: 2.5 sigma keeps ~80 %
            weight for typical inliers and < 1 % beyond 30 px.
        final_kernel: kernel of the solves with the body priors, after the first
            outlier rejection: ``"auto"`` (default), a kernel name, or ``None``
            (least squares). ``"auto"`` is least squares when the first pass
            rejected fewer than ``auto_kernel_fraction`` of the pairs (clean
            data: least squares on the inliers is the efficient estimator and
            converges in two iterations, where a Geman-McClure kernel made the
            first step overshoot and cost one to two more), else Geman-McClure
            (keypoints displaced along their epipolar line survive the first
            rejection and only show once the body priors pull them back; on a
            10 %-outlier scene least squares left 0.33 deg, Geman-McClure at
            20 px 0.04 deg).
        final_kernel_scale_px: scale of that kernel.
        auto_kernel_fraction: see ``final_kernel``.
        outlier_threshold_px: after the first solve, a pair whose reprojection
            residual exceeds this in either view is dropped; ``None``:
            ``2 * kernel_scale_px`` (Geman-McClure weight < 4 %).
        bone_outlier_k: a joint whose bones in a frame are all farther than this
            many robust standard deviations from their median length is an
            outlier too (0: off); catches keypoints displaced along the
            epipolar line, which reprojection cannot see.
        min_parallax_deg: pairs whose two rays (from the camera and from the
            virtual camera) meet at less than this angle, degrees, are left out of
            the graph (:func:`~mirrorgraph.graph.stages.parallax_deg`): their depth
            is held by nothing but the body priors.
        warm_start_min_parallax_deg: the same for the warm start, which has no body
            prior: a pair at 3 deg has ~10x the depth noise of one at 30 deg and
            adds next to nothing about the mirror (it lies near the epipole).
        warm_start_iterations: iterations on the reprojection terms alone before
            the first full solve (cheap: no coupling between points).
        warm_start_frames: frames (spread over the video) in that warm start; every
            pair is then triangulated with its mirror for the first rejection.
        outlier_pass_iterations: cap of the first full solve when outliers were
            found before it (it only has to expose the rest for the second rejection).
        resolve_after_rejection: solve the full graph again without what the first
            full solve's rejection dropped (where it dropped anything); ``False``: a
            first full solve that converged is final, what it dropped is left out of the
            noise, the retriangulation and the lengths only (the live run's windows,
            each followed by the next). A first solve stopped by
            ``outlier_pass_iterations``, or a focal length estimated, always solves
            again.
    """

    pixel_sigma: float = 4.0
    robust_kernel: Kernel | None = "geman_mcclure"
    kernel_scale_px: float = 10.0
    final_kernel: Kernel | Literal["auto"] | None = "auto"
    final_kernel_scale_px: float = 20.0
    auto_kernel_fraction: float = 0.01
    outlier_threshold_px: float | None = None
    bone_outlier_k: float = 5.0
    min_parallax_deg: float = 0.5
    warm_start_min_parallax_deg: float = 3.0
    warm_start_iterations: int = 4
    warm_start_frames: int = 300
    outlier_pass_iterations: int = 3
    resolve_after_rejection: bool = True

    def __post_init__(self) -> None:
        for name in ("robust_kernel", "final_kernel"):
            value = getattr(self, name)
            allowed = KERNELS + (("auto",) if name == "final_kernel" else ())
            if value is not None and value not in allowed:
                raise InputError(f"must be one of {', '.join(allowed)} or None, got {value!r}",
                                 field=name)
        if not (self.pixel_sigma > 0 and math.isfinite(self.pixel_sigma)):
            raise InputError(f"must be a positive number of pixels, got {self.pixel_sigma!r}",
                             field="pixel_sigma")

    @property
    def outlier_threshold(self) -> float:
        """The outlier threshold in pixels, default resolved."""
        if self.outlier_threshold_px is not None:
            return float(self.outlier_threshold_px)
        return 2.0 * float(self.kernel_scale_px)


@dataclass(frozen=True, kw_only=True)
class SolverOptions:
    """The linear solves: iterations, stopping rules, long videos, marginals.

    Levenberg-Marquardt on the reduced system of the mirror(s) and the bone lengths
    (:mod:`.optimizer`); videos longer than ``max_graph_frames`` in chunks
    (:mod:`.chunked`).

    Attributes:
        max_iterations: Levenberg-Marquardt iterations (linear solves) per solve.
        relative_tolerance: stop when an iteration lowers the error by less
            than this fraction.
        global_step_tolerance: or when it moved the mirror (and bone lengths, and a
            rig's poses) by less than this many standard deviations (Mahalanobis
            length), at any damping. 0.2 leaves at most ~0.2 sigma of the mirror
            unconverged (2 % in quadrature with its own sigma): on 7 scenes (4
            synthetic, 3 low-parallax, 600 frames), against 0.05, the rotation errors
            differ by at most 0.1 sigma (0.004 deg) and the linear solves are 7-9
            (synthetic) and 11-12 (low parallax) instead of 12-14, together with
            ``outlier_pass_iterations`` 3 instead of 5.
        max_graph_frames: longest video solved as one graph; longer ones are
            solved on a spread subset of this many frames, then in chunks of at
            most this many frames sharing the mirror and the bone lengths
            (:mod:`mirrorgraph.graph.chunked`; one graph of 1000 frames x 12
            joints peaks at ~100 MB).
        chunk_block_frames: length of the contiguous blocks of that subset.
        chunk_passes: most passes over the chunks (each ends with a shared step
            of the mirror and bone lengths).
        chunk_step_tolerance: stop the passes when that step (which is applied)
            is shorter than this many standard deviations; each pass leaves about a
            tenth of its step (measured: 7.5, 0.92, 0.02 sigma over three passes on
            10,000 frames), so one sigma leaves ~0.1 sigma and saves a pass.
        workers: processes that solve the chunks of a long video at once (the chunks
            are independent given the mirror; GTSAM holds the interpreter lock, so
            threads would not help); ``None``: the machine's cores, at most 4. Each
            holds one chunk's graph (~150-250 MB). The result does not depend on it.
        marginals: compute the plane's covariance.
        joints_uncertainty: with ``marginals``, each output joint's covariance too
            (:mod:`.joints_uncertainty`); ``False`` where no one reads it (the live
            run's windows).
    """

    max_iterations: int = 20
    relative_tolerance: float = 1e-5
    global_step_tolerance: float = 0.2
    max_graph_frames: int = 2000
    chunk_block_frames: int = 250
    chunk_passes: int = 1
    chunk_step_tolerance: float = 1.0
    workers: int | None = None
    marginals: bool = True
    joints_uncertainty: bool = True


@dataclass(frozen=True, kw_only=True)
class GaugeOptions:
    """The gauge: what fixes the scale and how the mirror link is held.

    2D keypoints fix the mirror's normal, not its distance: the scale is the subject's
    height (metres with ``subject_height``, else the mirror distance is 1).

    Attributes:
        subject_height: standing height in metres: fixes the scale (metres);
            ``None``: the mirror distance is 1.
        height_sigma: relative standard deviation of ``subject_height`` as given, the
            height's prior in the metric scale's std (``scale_rel_std``, with the
            measurement's own spread, :func:`mirrorgraph.stature.measurement_rel_std`),
            added to every reported length std (``distance_std``, camera positions,
            ``joints_std``). 1.3 % by default: a height the subject reports
            (adults over-report by 1.0-1.6 cm, S. Scholes et al., Health Survey for
            England 2011-16, 38,942 adults, medRxiv 10.1101/2022.01.28.22270014; 1.07 cm
            in the Danish DCH-NG cohort, 39,514 adults, medRxiv
            10.1101/2022.12.20.22283553; reported and measured heights correlate at
            r = 0.98, a difference std of 1.9 cm at an adult height std of 9.5 cm),
            bias and spread in quadrature, 2.2 cm, over a 1.7 m adult. A height
            measured: its measurement's own std (e.g. 0.005). The stature's own error
            with the height exact (Winter's fractions for the ~10 % of the height below
            the ankles and above the eyes, the reconstruction) is not in it: 0.2-0.75 %
            RMS on synthetic and the independent fixtures' scenes, 1.25 % on the CMU
            skeleton (``bench/RESULTS_joints_stated_uncertainty.md``).
        scale_from: how the subject's height becomes a length (with
            ``subject_height``): ``"stature"`` (default) rescales the solution so
            that the stature measured on its joints, ankle to eyes or head top,
            is the height (:mod:`mirrorgraph.stature`; falls back to ``"limbs"``
            and says so when the joints do not span it); ``"limbs"`` keeps the
            gauge's scale, the limb bones' sum at Winter's fractions of the height
            (for a subject who is not upright for most of the video: sitting,
            lying, bent over). On synthetic subjects (3 % per segment) the metric
            scale error is 0.33 % RMS with the stature, 1.59 % with the limbs
            (``bench/RESULTS_stature.md``).
        keypoint_offset: where the keypoints lie off the anatomical landmarks the
            stature's proportions are measured between, metres: the placement term of
            the metric scale's std (:func:`mirrorgraph.stature.keypoint_rel_std`, the
            limbs' :func:`~mirrorgraph.stature.limbs_rel_std`, the segments'
            :func:`~mirrorgraph.stature.segment_rel_std`). ``None`` (default): the
            literature's, :data:`mirrorgraph.anthropometry.KEYPOINT_OFFSET` of the
            height (3.0 cm at 1.75 m: video keypoint detectors against marker-based
            joint centres, Needham et al., *Sci. Rep.* 11, 20673, 2021). Lower it for
            keypoints that sit on the landmarks (2D projections of motion-capture
            markers, a detector validated on anatomical landmarks, synthetic
            keypoints); ``0`` leaves the height's prior and the measured spreads.
            Without ``subject_height`` it is unused.
        link_sigma_rotation, link_sigma_translation: sigmas of the mirror-link
            factor (rad, length unit) when it is used as a soft factor
            (``GraphProblem.full(links=True)`` for GTSAM's own optimisers); the
            refinement itself enforces the link exactly (:mod:`.reduction`).
    """

    subject_height: float | None = None
    height_sigma: float = 0.013
    scale_from: ScaleFrom = "stature"
    keypoint_offset: float | None = None
    link_sigma_rotation: float = 1e-6
    link_sigma_translation: float = 1e-6

    def __post_init__(self) -> None:
        if self.scale_from not in SCALE_FROM:
            raise InputError(f"must be one of {', '.join(SCALE_FROM)}, got {self.scale_from!r}",
                             field="scale_from")
        h = self.subject_height
        if h is not None and (isinstance(h, bool) or not isinstance(h, (int, float))
                              or not (math.isfinite(h) and h > 0)):
            raise InputError(f"must be a positive number of metres or None, got {h!r}",
                             field="subject_height")
        hs = self.height_sigma
        if (isinstance(hs, bool) or not isinstance(hs, (int, float))
                or not (math.isfinite(hs) and hs >= 0)):
            raise InputError(f"must be a non-negative fraction of the height (its relative "
                             f"std), got {hs!r}", field="height_sigma")
        o = self.keypoint_offset
        if o is not None and (isinstance(o, bool) or not isinstance(o, (int, float))
                              or not (math.isfinite(o) and o >= 0)):
            raise InputError(f"must be a non-negative number of metres (a keypoint's "
                             f"placement off its landmark) or None, got {o!r}",
                             field="keypoint_offset")


_GROUPS = {"priors": PriorOptions, "schedule": ScheduleOptions, "solver": SolverOptions,
           "gauge": GaugeOptions}


@dataclass(frozen=True, kw_only=True)
class RefineOptions(PriorOptions, ScheduleOptions, SolverOptions, GaugeOptions):
    """Every setting of the refinement: the four groups together.

    The fields are those of :class:`PriorOptions` (the body priors),
    :class:`ScheduleOptions` (noise model, kernels, outlier passes),
    :class:`SolverOptions` (iterations, stopping, chunks, marginals) and
    :class:`GaugeOptions` (scale and mirror link), documented there, and ``focal``,
    a :class:`FocalOptions` (how the intrinsics of a camera given without them are
    estimated; nested, as it applies to those cameras only); keyword arguments only. One object serves the single mirror
    (:func:`mirrorgraph.pipelines.solve.refine_mirror`)
    and rigs (:func:`mirrorgraph.pipelines.solve.solve_rig`): one solve driver, one
    configuration.

    Example:
        >>> opts = RefineOptions(bone_sigma=0.02, max_iterations=10)
        >>> opts.priors.bone_sigma, opts.solver.max_iterations
        (0.02, 10)
        >>> RefineOptions.from_groups(priors=PriorOptions(use_hip=False)).use_hip
        False
    """

    focal: FocalOptions = FocalOptions()

    def __post_init__(self) -> None:
        PriorOptions.__post_init__(self)
        ScheduleOptions.__post_init__(self)
        GaugeOptions.__post_init__(self)

    @classmethod
    def from_groups(cls, *, priors: PriorOptions | None = None,
                    schedule: ScheduleOptions | None = None,
                    solver: SolverOptions | None = None,
                    gauge: GaugeOptions | None = None,
                    focal: FocalOptions | None = None) -> "RefineOptions":
        """Join option groups (a group not given keeps its defaults)."""
        kw = {}
        for group in (priors, schedule, solver, gauge):
            if group is not None:
                kw.update({f.name: getattr(group, f.name) for f in fields(group)})
        if focal is not None:
            kw["focal"] = focal
        return cls(**kw)

    def _group(self, name: str):
        kind = _GROUPS[name]
        return kind(**{f.name: getattr(self, f.name) for f in fields(kind)})

    @property
    def priors(self) -> PriorOptions:
        """The body priors' settings."""
        return self._group("priors")

    @property
    def schedule(self) -> ScheduleOptions:
        """The robust schedule's settings."""
        return self._group("schedule")

    @property
    def solver(self) -> SolverOptions:
        """The linear solves' settings."""
        return self._group("solver")

    @property
    def gauge(self) -> GaugeOptions:
        """The gauge's settings."""
        return self._group("gauge")


def one_subject_height(given: float | None, options: GaugeOptions | None, where: str, *,
                       default: float | None = None) -> float | None:
    """The one subject height of a run whose front end takes it in two places.

    :func:`mirrorgraph.calibrate` takes ``CalibrateOptions.subject_height`` and
    :func:`mirrorgraph.calibrate_rig` its ``subject_height`` argument, beside the
    ``subject_height`` of the :class:`RefineOptions` they are given: either is taken,
    two different ones are refused, none is ignored.

    Args:
        given: the front end's own height, metres, or ``None``.
        options: the refinement's options (``None``: the defaults).
        where: how the front end names ``options`` in the message
            (``"refine_options"``, ``"options"``).
        default: the height where neither gives one (a rig file's), or ``None``.

    Returns:
        The height in metres, or ``None`` (no metric scale).

    Raises:
        InputError: two different heights, or one that is no human height
            (:func:`mirrorgraph.anthropometry.height_problem`), field ``subject_height``.
    """
    inner = None if options is None else options.subject_height
    if given is not None and inner is not None and float(given) != float(inner):
        raise InputError(f"{given!r} differs from {where}.subject_height {inner!r}: give the "
                         "height once", field="subject_height")
    height = next((h for h in (given, inner, default) if h is not None), None)
    if height is not None and height_problem(height):
        raise InputError(height_problem(height), field="subject_height")
    return height
