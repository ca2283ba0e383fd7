"""Options of the factor-graph refinement (:func:`mirrorgraph.graph.refine_mirror`).

Every prior's weight is given as a standard deviation ``sigma`` (weight
``1 / sigma^2`` in the whitened least-squares objective). Lengths are relative
to the subject's height ``h`` in the graph's length unit: the given
``subject_height`` (metres), or without it the height implied by the initial
triangulation's median bone lengths and Winter's proportions (in units of the
mirror distance). That keeps the defaults valid whatever the gauge.

How the defaults were chosen (synthetic scenes of
:func:`mirrorgraph.synth.make_scene`, COCO-17, 1000 frames at 30 fps, 4 px noise,
seeds 0-9, initial normal 1 deg off; paired comparisons: every setting on the same
noise draws, plus Monte Carlo noise draws on fixed scenes; ``/bench/bench_graph.py``
reproduces the protocol):

* ``pixel_sigma`` is the noise the paper simulates; the Geman-McClure scale of
  2.5 sigma and the 2x-scale rejection threshold keep every inlier (their 99.9th
  percentile residual is ~13 px) and cut outliers displaced by 30-150 px.
* Bones where their length is measured without bias (``bone_bias_limit``). A
  bone's length measured from noisy joints is too long on average by up to
  ``tr(Sigma_a + Sigma_b) / (2 L)`` (its curvature), centimetres where the two
  rays of a joint meet at a small angle (the person near the line from the camera
  to the mirror): the joint optimum of the mirror and the per-frame depths with
  such bones is biased however many frames there are. Monte Carlo (6 scenes a
  slice, 3 noise draws each, iid 4 px, 1000 frames; RMS error over the bound):
  every bone in every frame 1.60 (gym 1.64, low parallax 2.10), the rule at
  ``c = 0.3`` 1.01, at 1 1.08, at 3 1.22, no bone 0.93 (``bench/RESULTS_priors.md``).
  Under iid noise the rule's bones cost the mirror ~8 % of a bound against no
  bone; under a realistic detector (per-label bias, AR(1) noise, outliers along
  epipolar lines) they help in some scenes and hurt in others (medians 8.9 vs 8.7
  bounds). They stay in the calibration because they make the body metric (the
  subject-height gauge is a sum of bone lengths) and its gross outliers visible
  (``bone_outlier_k``); every bone holds the joints in the joints pass, where the
  mirror is held.
* The symmetry and anthropometry sigmas act on the bone lengths only; they are
  loose bounds for real people (a detector's "joints" move within the body by a
  few percent of a bone).
* ``smoothness_sigma`` in the calibration graph (``use_smoothness``, off): a
  loose acceleration prior (0.8 h per frame^2) does not move the mirror (Monte
  Carlo as above: RMS error over the bound 1.27 with it, 1.24 without), a tight
  one *biases* it on noisy data (16 draws on one scene: mean rotation error 0.31
  deg at 0.003 h, 0.09 deg at 0.01 h), and it couples the frames, so the
  elimination is banded instead of frame by frame: 2.2x the time of a linear
  solve (140 vs 45 ms on 1000 frames). The 3D motion gets its smoothness in the
  joints pass (``joints_smoothness_sigma``), with the mirror held.
* ``hip_sigma`` (BODY-25 only): 0.1, the hips are colinear to a few degrees.
"""

from __future__ import annotations

from dataclasses import dataclass

#: The ways a subject height becomes a length (``RefineOptions.scale_from``).
SCALE_FROM = ("stature", "limbs")

__all__ = ["RefineOptions", "FocalOptions"]


@dataclass(frozen=True)
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
        principal_point: estimate the principal point ``(cx, cy)`` too (default: held
            at the image centre, where phones and webcams have it within a few per
            cent of the image; it is poorly determined from people).
        search_fov_deg: the focal length's initial search (one camera and its mirrors,
            :func:`~mirrorgraph.graph.stages.focal_search`) spans these horizontal
            fields of view, degrees.
        search_steps: candidate focal lengths of that search (log-spaced; the best is
            refined by a parabola through its neighbours).
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
            Between the two the estimate stays: on a wide scene whose estimate had a
            std of 6.5 % its error was 6.5 %, the guess's 30 %.
    """

    principal_point: bool = False
    search_fov_deg: tuple[float, float] = (20.0, 120.0)
    search_steps: int = 9
    search_frames: int = 150
    bone_bias_limit: float | None = 1.0
    prior_rel_sigma: float = 0.5
    anthropometry: bool = False
    undetermined_rel_std: float = 0.05
    fallback_rel_std: float = 0.2


@dataclass(frozen=True)
class RefineOptions:
    """Weights, kernel, gauge and solver settings of the refinement.

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
        smoothness_sigma: ``L_smooth``, acceleration per frame^2, fraction of ``h``.
        smoothness_max_gap: longest frame step bridged by a smoothness factor.
        joints_smoothness_sigma: after the mirror is found, the 3D joints are solved
            once more with the mirror and the bone lengths held and this (tighter)
            smoothness, fraction of ``h`` per frame^2; ``None`` skips that pass (the
            joints are then the calibration's). The mirror wants a loose prior (a
            tight one biases it), the motion a tight one (it halves the joints'
            error: PA-MPJPE 15-20 -> 9-11 mm on protocol and CMU scenes, mirror
            unchanged, +0.4 s per 1000 frames): the two passes give each its own.
            Videos solved in chunks (longer than ``max_graph_frames``) get it
            chunk by chunk with the final mirror.
        use_bone_length, use_symmetry, use_anthropometry, use_hip, use_smoothness:
            switch each prior of the calibration graph (the hip prior also needs a
            mid-hip joint; the subject-height gauge needs the bone lengths, so it
            keeps them on; the smoothness is off: see the module docstring, the
            joints pass has its own).
        subject_height: standing height in metres: fixes the scale (metres);
            ``None``: the mirror distance is 1.
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
        height_sigma: relative standard deviation of the metric scale, added to
            every reported length std (``distance_std``, camera positions): the
            subject's proportions where the stature is not measured, the
            detector's placement of the keypoints and the height's own
            measurement. 2 % by default: conservative on synthetic subjects
            (0.3 % RMS with the stature), not measured on real video.
        link_sigma_rotation, link_sigma_translation: sigmas of the mirror-link
            factor (rad, length unit) when it is used as a soft factor
            (``GraphProblem.full(links=True)`` for GTSAM's own optimisers); the
            refinement itself enforces the link exactly (:mod:`.reduction`).
        max_iterations: Levenberg-Marquardt iterations (linear solves) per solve.
        outlier_pass_iterations: cap of the first full solve when outliers were
            found before it (it only has to expose the rest for the second rejection).
        relative_tolerance: stop when an iteration lowers the error by less
            than this fraction.
        global_step_tolerance: or when it moved the mirror (and bone lengths, and a
            rig's poses) by less than this many standard deviations (Mahalanobis
            length), at any damping. 0.2 leaves at most ~0.2 sigma of the mirror
            unconverged (2 % in quadrature with its own sigma): measured on 7 scenes
            (4 synthetic, 3 low-parallax, 600 frames) against 0.05, rotation errors
            changed by at most 0.1 sigma (0.004 deg) and the linear solves fell
            from 12-14 to 7-9 (synthetic) and 11-12 (low parallax), together with
            ``outlier_pass_iterations`` 3 instead of 5.
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
        focal: :class:`FocalOptions`, for the cameras whose focal length is estimated.
    """

    pixel_sigma: float = 4.0
    robust_kernel: str | None = "geman_mcclure"
    kernel_scale_px: float = 10.0
    final_kernel: str | None = "auto"
    final_kernel_scale_px: float = 20.0
    auto_kernel_fraction: float = 0.01
    outlier_threshold_px: float | None = None
    bone_outlier_k: float = 5.0

    bone_sigma: float = 0.01
    bone_bias_limit: float | None = 0.3
    symmetry_sigma: float = 0.005
    anthropometry_sigma: float = 0.05
    hip_sigma: float = 0.1
    smoothness_sigma: float = 0.8
    smoothness_max_gap: int = 4
    joints_smoothness_sigma: float | None = 0.01
    use_bone_length: bool = True
    use_symmetry: bool = True
    use_anthropometry: bool = True
    use_hip: bool = True
    use_smoothness: bool = False

    subject_height: float | None = None
    height_sigma: float = 0.02
    scale_from: str = "stature"

    link_sigma_rotation: float = 1e-6
    link_sigma_translation: float = 1e-6

    max_iterations: int = 20
    outlier_pass_iterations: int = 3
    relative_tolerance: float = 1e-5
    global_step_tolerance: float = 0.2
    min_parallax_deg: float = 0.5
    warm_start_min_parallax_deg: float = 3.0
    warm_start_iterations: int = 4
    warm_start_frames: int = 300
    max_graph_frames: int = 2000
    chunk_block_frames: int = 250
    chunk_passes: int = 1
    chunk_step_tolerance: float = 1.0
    workers: int | None = None
    marginals: bool = True
    focal: FocalOptions = FocalOptions()

    def __post_init__(self) -> None:
        if self.scale_from not in SCALE_FROM:
            from ..errors import InputError
            raise InputError(f"scale_from must be one of {', '.join(SCALE_FROM)}, "
                             f"got {self.scale_from!r}", field="scale_from")

    @property
    def outlier_threshold(self) -> float:
        """The outlier threshold in pixels, default resolved."""
        if self.outlier_threshold_px is not None:
            return float(self.outlier_threshold_px)
        return 2.0 * float(self.kernel_scale_px)
