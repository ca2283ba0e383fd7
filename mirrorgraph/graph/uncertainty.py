"""The headline uncertainty of a calibration: the robust figures and their confidence regions.

Of the marginal covariance (independent pixel noise) and the sandwich's figures
(:mod:`.sandwich`: over time, over joint pairs, both, the jackknives) the largest
rotation std is the headline (:func:`robust_normal_cov` for a mirror's normal,
:func:`robust_blocks` for a rig's cameras and mirrors, :func:`robust_intrinsics_std`
for estimated intrinsics), widened where thinner than the marginals
(:func:`~.sandwich.covariance_max`). Its 90 % region takes the clusters' own sampling
noise into account: Hotelling's ``T^2`` quantile for a covariance estimated from
``G`` clusters, the ``chi^2`` one for the marginals and the time series
(:func:`region_threshold`, :func:`region_rotation_deg`; Cameron and Miller 2015). Rotations in
degrees, intrinsics in pixels.
"""

from __future__ import annotations

import math

import gtsam
import numpy as np

from .result import normal_cov_from_tangent, rotation_std_from_normal_cov
from .sandwich import covariance_max, sandwich, sandwich_candidates
from .scores import JointScores

#: A camera or mirror whose rotation std (the robust figure) exceeds this many degrees
#: is reported as poorly determined (a mirror seen almost edge-on or square-on, too few
#: frames, too little motion, or a detector's error that the frames do not average).
POORLY_DETERMINED_DEG = 0.5

__all__ = ["POORLY_DETERMINED_DEG", "ROBUST_PARTS", "REGION_LEVEL", "robust_normal_cov",
           "robust_blocks", "robust_intrinsics_std", "region_threshold", "region_rotation_deg",
           "intrinsics_contributions"]




def robust_intrinsics_std(scores: JointScores, marginal: dict[int, np.ndarray]
                          ) -> dict[int, tuple[np.ndarray, str]]:
    """The headline standard deviations of every estimated camera's intrinsics.

    As :func:`robust_normal_cov` for the reduced block of each camera's ``K(c)``
    (``f`` or ``f, cx, cy``, px): of the marginal covariance and the sandwich's
    figures (:data:`ROBUST_PARTS`), the largest standard deviation of each entry.

    Args:
        scores: :func:`~.scores.frame_scores` of the solution.
        marginal: ``K(c)`` key -> its ``(d, d)`` marginal covariance (scaled by the noise).

    Returns:
        ``K(c)`` key -> ``((d,) stds px, the name of the figure that gave the focal's)``.
    """
    cands = sandwich_candidates(sandwich(scores))
    out, off = {}, 0
    for key, dim in scores.z_keys:
        block = slice(off, off + dim)
        off += dim
        if key not in marginal:
            continue
        best = np.sqrt(np.maximum(np.diag(np.asarray(marginal[key], float)), 0.0))
        chosen = "marginal"
        for name, C in cands.items():
            std = np.sqrt(np.maximum(np.diag(C[block, block]), 0.0))
            if np.all(np.isfinite(std)):
                if std[0] > best[0]:
                    chosen = name
                best = np.maximum(best, std)
        out[int(key)] = (best, chosen)
    return out


#: The figures :func:`robust_normal_cov` chooses from, largest rotation std first wins.
ROBUST_PARTS = ("marginal", "time", "joint", "two_way", "jack_time", "jack_joint")


def robust_normal_cov(scores: JointScores, basis: np.ndarray, marginal: np.ndarray
                      ) -> tuple[np.ndarray, dict]:
    """The headline covariance of a mirror's unit normal, and what it is made of.

    Of the marginal covariance (iid noise), the sandwich seeing the time series alone,
    the joint-pair clusters alone and both together (:func:`~.sandwich.sandwich`), the one with
    the largest rotation std, widened where it is thinner than the marginals
    (:func:`~.sandwich.covariance_max`): each is an estimate with its own noise (with six pairs
    of joints the clusters' is a six-degree-of-freedom one, which the two-way
    combination's subtraction can take below either part), and an uncertainty a user
    plans on must not be the lucky one.

    Args:
        scores: :func:`~.scores.joint_scores` of a single mirror (reduced coordinates: the plane).
        basis: ``(3, 2)`` the plane's normal tangent basis (the scores' coordinates).
        marginal: ``(3, 3)`` the marginal covariance of the normal (scaled by the noise).

    Returns:
        ``(3, 3)`` covariance (camera frame, rad^2) and a record: each candidate's
        rotation std (deg) and ``(3, 3)`` covariance, the chosen one, the ratio to the
        marginal std, the time series' bandwidth (frames), the chosen figure's clusters
        (0: none), the 90 % region's squared radius (:func:`region_threshold`) and its
        largest rotation error ``rotation_90_deg`` (twice the normal's largest angle in
        the region, deg).
    """
    sw = sandwich(scores)
    covs = {"marginal": np.asarray(marginal, dtype=float),
            "time": normal_cov_from_tangent(basis, sw["cov_time"][:2, :2]),
            "joint": normal_cov_from_tangent(basis, sw["cov_joint"][:2, :2]),
            "two_way": normal_cov_from_tangent(basis, sw["cov"][:2, :2]),
            "jack_time": normal_cov_from_tangent(basis, sw["cov_jack_time"][:2, :2]),
            "jack_joint": normal_cov_from_tangent(basis, sw["cov_jack_joint"][:2, :2])}
    stds = {k: rotation_std_from_normal_cov(c) for k, c in covs.items()}
    finite = [k for k in ROBUST_PARTS if np.isfinite(stds[k])]
    chosen = max(finite, key=lambda k: stds[k]) if finite else "marginal"
    # no thinner than the marginals in any direction (a cluster estimate from six pairs
    # can be nearly flat in one): the smallest covariance above both
    headline = covariance_max(covs["marginal"], covs[chosen])
    std = rotation_std_from_normal_cov(headline)
    clusters = {"jack_time": int(sw["segments"]), "joint": len(np.unique(scores.clusters)),
                "two_way": len(np.unique(scores.clusters)),
                "jack_joint": len(np.unique(scores.clusters))}.get(chosen)
    m2 = region_threshold(2, clusters, REGION_LEVEL)
    parts = {f"{k}_rotation_std_deg": float(stds[k]) for k in ROBUST_PARTS}
    full = sw["bread"] if chosen == "marginal" else sandwich_candidates(sw)[chosen]
    parts.update({f"{k}_normal_cov": covs[k] for k in ROBUST_PARTS},
                 contributions=intrinsics_contributions(full, scores.z_keys),
                 chosen=chosen, bandwidth_frames=float(sw["bandwidth"]),
                 segments=int(sw["segments"]), clusters=int(clusters or 0),
                 region90_mahalanobis2=float(m2),
                 rotation_90_deg=region_rotation_deg(headline, clusters),
                 ratio_to_marginal=float(std / stds["marginal"])
                 if stds["marginal"] > 0 else float("nan"))
    return headline, parts


def intrinsics_contributions(cov: np.ndarray, z_keys: list, block: slice = slice(0, 2)
                             ) -> dict[str, float]:
    """How much of a rotation's variance the unknown intrinsics make.

    With ``C`` the covariance of the reduced coordinates, ``a`` the rotation's block
    (a plane's first two: its normal) and ``x`` one group of intrinsics, the variance
    ``a`` would lose were ``x`` known is ``C_ax C_xx^-1 C_xa`` (Gaussian conditioning);
    its trace over ``tr C_aa`` is that group's share.

    Args:
        cov: ``(n, n)`` covariance over ``z_keys`` (any scale: the shares are ratios).
        z_keys: ``(key, dim)`` of the reduced coordinates; an intrinsics block (a
            ``k`` key) is ``f`` or ``f, cx, cy`` (:mod:`.reduction`).
        block: the rotation's coordinates in ``cov``.

    Returns:
        ``{"focal_length": share, "principal_point": share}`` (0-1; the groups the
        coordinates hold; the rest of the variance is the geometry's and the noise's).
    """
    C = 0.5 * (np.asarray(cov, float) + np.asarray(cov, float).T)
    groups: dict[str, list[int]] = {}
    off = 0
    for key, dim in z_keys:
        if gtsam.Symbol(key).chr() == ord("k"):
            groups.setdefault("focal_length", []).append(off)
            if dim == 3:
                groups.setdefault("principal_point", []).extend([off + 1, off + 2])
        off += dim
    a = np.arange(C.shape[0])[block]
    total = float(np.trace(C[np.ix_(a, a)]))
    out = {}
    for name, idx in groups.items():
        x = np.asarray(idx)
        Cax, Cxx = C[np.ix_(a, x)], C[np.ix_(x, x)]
        if not (np.all(np.isfinite(Cax)) and np.all(np.isfinite(Cxx))) or total <= 0:
            out[name] = float("nan")
            continue
        out[name] = float(np.clip(np.trace(Cax @ np.linalg.pinv(Cxx) @ Cax.T) / total, 0, 1))
    return out


#: The confidence level of the region :func:`robust_normal_cov` reports.
REGION_LEVEL = 0.9


def region_threshold(dim: int, clusters: int | None, level: float = REGION_LEVEL) -> float:
    """The squared Mahalanobis radius of a ``level`` confidence region of ``dim`` parameters.

    A covariance estimated from ``G`` independent clusters (joint pairs, time segments)
    is itself uncertain with ``G - 1`` degrees of freedom; the region then follows
    Hotelling's ``T^2 = dim (G - 1) / (G - dim) F(dim, G - dim)`` (Cameron and Miller
    2015, small-cluster inference), wider than the Gaussian's ``chi^2(dim)``, which it
    is for ``G`` large or for the marginals and the time series' long-run covariance
    (``clusters=None``). For ``dim = 2`` both quantiles have closed forms
    (``chi^2(2)`` is exponential: ``-2 log(1 - level)``; ``F(2, d)``'s survival function
    is ``(1 + 2 x / d)^(-d / 2)``); any other ``dim`` asks :mod:`scipy.special`.

    Args:
        dim: parameters (2 for a unit normal); clusters: ``G``, or ``None``.
        level: the confidence level, in ``(0, 1)``.

    Returns:
        the threshold ``c``: the region is ``delta^T Sigma^-1 delta <= c``.
    """
    gaussian = clusters is None or clusters <= dim
    if dim == 2:
        if gaussian:
            return -2.0 * math.log1p(-level)
        d = int(clusters) - 2
        quantile = 0.5 * d * math.expm1(-2.0 / d * math.log1p(-level))
    else:
        from scipy.special import chdtri, fdtri     # only here: ~0.3 s of a command's start
        if gaussian:
            return float(chdtri(dim, 1.0 - level))
        quantile = float(fdtri(dim, int(clusters) - dim, level))
    G = int(clusters)
    return float(dim * (G - 1) / (G - dim) * quantile)


def region_rotation_deg(normal_cov: np.ndarray, clusters: int | None = None,
                        level: float = REGION_LEVEL) -> float:
    """The largest virtual-camera rotation error in a mirror normal's confidence region.

    Args:
        normal_cov: ``(3, 3)`` covariance of the unit normal (camera frame, rad^2).
        clusters: as :func:`region_threshold`; level: the confidence level.

    Returns:
        ``2 sqrt(c lambda_max)`` in degrees: the mirror turns the virtual camera by
        twice the normal's angle.
    """
    C = np.asarray(normal_cov, dtype=float)
    if not np.all(np.isfinite(C)):
        return float("nan")
    lam = float(np.linalg.eigvalsh(0.5 * (C + C.T))[-1])
    return float(2.0 * np.degrees(np.sqrt(region_threshold(2, clusters, level) * max(lam, 0.0))))


def robust_blocks(scores: JointScores, marginal_blocks: list[np.ndarray]
                  ) -> tuple[list[np.ndarray], list[dict]]:
    """Headline covariances of a rig's estimated cameras and mirrors, block by block.

    As :func:`robust_normal_cov` for each reduced variable of ``scores.z_keys`` (a
    camera pose: its rotation block, the first three tangent coordinates; a plane:
    its normal block, the first two): the candidate with the largest trace there,
    widened where thinner than the marginals (:func:`~.sandwich.covariance_max`); the rest of the
    block (a position, a distance, whose reprojection-only figure depends on the
    scale gauge) is the marginal one scaled by the same ratio of stds.

    Args:
        scores: :func:`~.scores.joint_scores` of the rig.
        marginal_blocks: the marginal covariance of each reduced variable, in
            ``scores.z_keys`` order (scaled by the noise).

    Returns:
        the headline blocks and, per block, ``{"chosen", "ratio_to_marginal",
        "contributions"}`` (the unknown intrinsics' shares of its rotation's variance,
        :func:`intrinsics_contributions`).
    """
    sw = sandwich(scores)
    cands = sandwich_candidates(sw)
    out, parts, off = [], [], 0
    for (key, dim), M in zip(scores.z_keys, marginal_blocks):
        M = np.asarray(M, dtype=float)
        rot = slice(0, 3) if dim == 6 else slice(0, 2)
        block = slice(off, off + dim)
        off += dim
        mrot = M[rot, rot]
        best, best_tr = "marginal", float(np.trace(mrot))
        for name, C in cands.items():
            B = C[block, block][rot, rot]
            if np.all(np.isfinite(B)) and np.trace(B) > best_tr:
                best, best_tr = name, float(np.trace(B))
        head = mrot if best == "marginal" else covariance_max(mrot, cands[best][block, block][rot, rot])
        tr = float(np.trace(mrot))
        ratio = float(np.sqrt(np.trace(head) / tr)) if tr > 0 else 1.0
        H = M * ratio ** 2
        H[rot, rot] = head
        out.append(H)
        full = sw["bread"] if best == "marginal" else cands[best]
        parts.append({"chosen": best, "ratio_to_marginal": ratio,
                      "contributions": intrinsics_contributions(
                          full, scores.z_keys, slice(block.start + rot.start,
                                                     block.start + rot.stop))})
    return out, parts
