"""Bone lengths measured from triangulated joints, and their curvature bias.

A rig's bones between estimated joints (:func:`bone_table`), their median lengths
(:func:`median_bone_lengths`), the subject's height and the gauge's scale from them
against Winter's segment fractions (:func:`body_height_from_points`,
:func:`gauge_scale`; Winter, *Biomechanics and Motor Control of Human Movement*, 4th
ed., 2009), the second-order bias of a length measured from noisy joints
(:func:`bone_curvature_bias`) and lengths free of it, by moments (:func:`debiased_bone_lengths`)
or by the likelihood with each frame's bone direction integrated out
(:func:`integrated_bone_lengths`).
Lengths in the points' unit (graph units), joints ``(T, J, 3)`` in the world frame.
"""

from __future__ import annotations

import numpy as np

from ..anthropometry import expected_bone_lengths, height_fractions
from ..geometry import triangulation_covariance
from .rig import Rig, view_projections

__all__ = ["bone_table", "median_bone_lengths", "body_height_from_points", "gauge_scale",
           "bone_curvature_bias", "debiased_bone_lengths", "integrated_bone_lengths",
           "WATSON_KAPPAS", "BONE_OUTLIER_RATE", "LIKELIHOOD_FRAMES", "GRID_FRAMES"]


def bone_table(rig: Rig) -> tuple[list[str], np.ndarray]:
    """Bones whose two joints are both estimated: names and ``(B, 2)`` joint indices."""
    sk = rig.skeleton
    keep = set(np.asarray(rig.joints, dtype=int).tolist())
    names, pairs = [], []
    for name, (a, b) in zip(sk.bone_names, sk.bone_index):
        if int(a) in keep and int(b) in keep:
            names.append(name)
            pairs.append((int(a), int(b)))
    return names, np.array(pairs, dtype=int).reshape(-1, 2)


def median_bone_lengths(points: np.ndarray, pairs: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """``(B,)`` median over the frames of ``mask`` (``(T, B)``) of each bone's length
    (NaN for a bone never in ``mask``)."""
    d = np.linalg.norm(np.asarray(points, float)[:, pairs[:, 0]]
                       - np.asarray(points, float)[:, pairs[:, 1]], axis=-1)
    with np.errstate(invalid="ignore"):
        return np.array([np.median(d[mask[:, b], b]) if mask[:, b].any() else np.nan
                         for b in range(len(pairs))])


def body_height_from_points(rig: Rig, points: np.ndarray, used: np.ndarray) -> float:
    """Subject height in the points' length unit, from median bone lengths (Winter's fractions).

    Args:
        points: ``(T, J, 3)``; used: ``(T, J)`` bool.

    Returns:
        The median over bones of ``median_t |X_a - X_b| / fraction``; NaN if no bone is seen.
    """
    names, pairs = bone_table(rig)
    fr = height_fractions(rig.skeleton)
    est = []
    for name, (a, b) in zip(names, pairs):
        ok = used[:, a] & used[:, b]
        if ok.any():
            est.append(np.median(np.linalg.norm(points[ok, a] - points[ok, b], axis=1)) / fr[name])
    return float(np.median(est)) if est else float("nan")


def gauge_scale(rig: Rig, points: np.ndarray, used: np.ndarray, height: float) -> float:
    """Factor that makes the per-bone median lengths sum to Winter's lengths for ``height``."""
    names, pairs = bone_table(rig)
    expected = expected_bone_lengths(rig.skeleton, height)
    total, want = 0.0, 0.0
    for name, (a, b) in zip(names, pairs):
        ok = used[:, a] & used[:, b]
        if ok.any():
            total += float(np.median(np.linalg.norm(points[ok, a] - points[ok, b], axis=1)))
            want += expected[name]
    return want / total if total > 0 else 1.0


def bone_curvature_bias(rig: Rig, points: np.ndarray, used: np.ndarray,
                        planes: list[tuple[np.ndarray, float]], pairs: np.ndarray,
                        lengths: np.ndarray, pixel_sigma: float) -> np.ndarray:
    """``(T, B)`` bound on the second-order bias of each bone's length measured from noisy joints.

    A bone's length ``|X_a - X_b|`` is a curved function of its joints: noise across
    the bone lengthens it on average by ``tr(P S) / (2 L)`` (the expectation of
    ``|x + e|`` to second order in ``e``), ``S = Sigma_a + Sigma_b`` the two joints'
    triangulation covariances (:func:`~mirrorgraph.geometry.triangulation_covariance`),
    ``P = I - u u^T`` the projection across the bone's direction ``u``, ``L`` its
    length. Where the joints' rays meet at a small angle their depth error is
    centimetres and a bone across the line of sight (a standing person's thigh seen
    from the front) is measured decimetres long on average: a bone-length factor
    there is a biased measurement, and the joint optimum of the mirror and the
    per-frame depths with it is biased too, however many frames there are (Neyman
    and Scott's incidental parameters).

    The bound ``tr(S) / (2 L)`` is returned, which does not depend on the bone's
    measured direction: a rule that kept a bone where its *measured* direction runs
    along the line of sight would keep exactly the frames whose depth noise made it
    long (a selection bias of the same sign).

    Args:
        points: ``(T, J, 3)`` joints (world frame); used: ``(T, J)`` bool.
        planes: ``(n, d)`` per mirror; pairs: ``(B, 2)`` joint indices of the bones.
        lengths: ``(B,)`` each bone's length (the points' unit).
        pixel_sigma: pixel noise, px.

    Returns:
        The bound in the points' length unit; NaN where a joint is not used.
    """
    masks = [np.asarray(v.mask, bool) & used for v in rig.views]
    cov = triangulation_covariance(view_projections(rig, None, planes), points, masks,
                                   pixel_sigma)                                  # (T, J, 3, 3)
    var = np.trace(cov, axis1=-2, axis2=-1)                                     # (T, J)
    total = var[:, pairs[:, 0]] + var[:, pairs[:, 1]]
    return total / (2.0 * np.maximum(np.asarray(lengths, dtype=float), 1e-12))


def debiased_bone_lengths(rig: Rig, points: np.ndarray, used: np.ndarray,
                          planes: list[tuple[np.ndarray, float]], pairs: np.ndarray,
                          pixel_sigma: float, outlier_k: float = 10.0,
                          min_frames: int = 10) -> np.ndarray:
    """``(B,)`` bone lengths from noisy triangulated joints, free of the curvature bias.

    ``E |d|^2 = L^2 + tr(S)`` for a bone ``d = X_a - X_b`` measured with zero-mean noise
    of covariance ``S = Sigma_a + Sigma_b``, whatever the bone's direction (the
    corrected-score idea of measurement-error models: Stefanski 1989, Nakamura 1990).
    So ``L^2`` is estimated by the mean over frames of ``|d|^2 - tr(S)``
    (:func:`~mirrorgraph.geometry.triangulation_covariance`), where the median of
    ``|d|`` would be decimetres long for joints whose rays meet at a small angle
    (:func:`bone_curvature_bias`). Values beyond ``outlier_k`` robust standard
    deviations (1.4826 MAD) of their median are left out first (a mean, unlike a
    trimmed one, stays unbiased on the skewed distribution of ``|d|^2``; a cut at 5
    MAD took that skewed tail off a forearm at low parallax, 4 % short, at 10 MAD
    the lengths of three low-parallax scenes are 0.07 % short on average, 1.4 % at
    most).

    Args:
        points: ``(T, J, 3)`` joints triangulated from the views (not pulled by priors);
            used: ``(T, J)`` bool.
        planes: ``(n, d)`` per mirror; pairs: ``(B, 2)`` joint indices.
        pixel_sigma: pixel noise, px.
        outlier_k: the outlier cut, robust standard deviations.
        min_frames: frames a bone needs.

    Returns:
        The lengths in the points' unit; NaN for a bone seen in under ``min_frames``
        frames or whose corrected square is not positive.
    """
    masks = [np.asarray(v.mask, bool) & used for v in rig.views]
    cov = triangulation_covariance(view_projections(rig, None, planes), points, masks,
                                   pixel_sigma)
    var = np.trace(cov, axis1=-2, axis2=-1)                                     # (T, J)
    pts = np.asarray(points, dtype=float)
    sq = np.sum((pts[:, pairs[:, 0]] - pts[:, pairs[:, 1]]) ** 2, axis=-1)      # (T, B)
    corrected = sq - var[:, pairs[:, 0]] - var[:, pairs[:, 1]]
    out = np.full(len(pairs), np.nan)
    for b in range(len(pairs)):
        v = corrected[:, b][np.isfinite(corrected[:, b])]
        if len(v) < min_frames:
            continue
        med = np.median(v)
        mad = 1.4826 * np.median(np.abs(v - med))
        m = float(np.mean(v[np.abs(v - med) <= outlier_k * mad])) if mad > 0 else float(med)
        if m > 0:
            out[b] = np.sqrt(m)
    return out


#: Concentrations ``kappa`` of the Watson direction prior :func:`integrated_bone_lengths`
#: chooses among (its maximum-likelihood one, each bone's own): a girdle across the line
#: of sight (``kappa < 0``, angular width ``1 / sqrt(2 |kappa|)``), the uniform sphere
#: (``0``), a bipolar spread along it (``kappa > 0``).
WATSON_KAPPAS = np.concatenate([-np.geomspace(1.0, 256.0, 5)[::-1], [0.0],
                                np.geomspace(1.0, 256.0, 5)])

#: Share of the frames :func:`integrated_bone_lengths` lets be outliers (a keypoint moved
#: along its epipolar line, a left/right confusion): their density is uniform over a ball
#: five times the bone's median measured length.
BONE_OUTLIER_RATE = 0.05

#: Most frames (evenly spread over the clip) a bone's likelihood is evaluated on, for its
#: cost (each frame ~70 quadrature nodes times the concentrations, per candidate
#: length): on six low-parallax scenes the lengths from 300 frames are those from 1000
#: to 0.5 % (median), 2.7 % at most.
LIKELIHOOD_FRAMES = 300

#: Most frames of each bone (evenly spread) the coarse grid of candidate lengths that
#: brackets the likelihood's peak in :func:`integrated_bone_lengths` is evaluated on
#: (the peak is then found on all its frames).
GRID_FRAMES = 60

_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(4)


def _log_watson_norm(kappa: np.ndarray) -> np.ndarray:
    """``log int_{-1}^{1} exp(kappa c^2) dc`` for each ``kappa`` (Dawson's integral for
    ``kappa > 0``, the error function for ``kappa < 0``)."""
    from scipy.special import dawsn, erf

    k = np.asarray(kappa, dtype=float)
    out = np.full(k.shape, np.log(2.0))
    pos, neg = k > 0, k < 0
    sp, sn = np.sqrt(k[pos]), np.sqrt(-k[neg])
    out[pos] = np.log(2.0) + k[pos] + np.log(dawsn(sp) / sp)
    out[neg] = np.log(np.sqrt(np.pi) * erf(sn) / sn)
    return out


def _watson_weights(u: np.ndarray, kappas: np.ndarray) -> np.ndarray:
    """``(K, ...)`` ``exp(kappa (u - 1))`` for ``kappa > 0``, ``exp(kappa u)`` otherwise
    (``u = c^2`` in ``[0, 1]``: the Watson density's kernel, at most 1), for each of
    ``kappas``. A concentration twice another of its sign is the square of that one's
    weight: :data:`WATSON_KAPPAS` (powers of four) takes two exponentials and squarings
    where one exponential each would cost ten times as much (rounding: a relative
    ``2^k`` ulps after ``k`` squarings)."""
    u = np.asarray(u, dtype=float)
    out = np.empty((len(kappas),) + u.shape)
    done: dict[float, int] = {}
    for k in np.argsort(np.abs(kappas), kind="stable"):
        kappa = float(kappas[k])
        root, steps = None, 0
        for prev, i in done.items():
            if prev == 0.0 or np.sign(prev) != np.sign(kappa):
                continue
            ratio = kappa / prev
            steps = int(round(np.log2(ratio))) if ratio > 1 else -1
            if steps >= 1 and 2.0 ** steps == ratio:
                root = out[i]
                break
        w = out[k]
        if root is None:
            np.multiply(u - 1.0 if kappa > 0 else u, kappa, out=w)
            np.exp(w, out=w)
        else:
            np.multiply(root, root, out=w)
            for _ in range(steps - 1):
                np.multiply(w, w, out=w)
        done[kappa] = k
    return out


def _depth_frame(d: np.ndarray, cov: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each frame's bone ``d`` ``(T, 3)`` in its noise's frame (``cov`` ``(T, 3, 3)``):
    ``z`` along the long axis (the line of sight at low parallax), ``r`` the length
    across it, the variance ``var_z`` along it and ``var_r`` across it (the geometric
    mean of the two smaller eigenvalues)."""
    w, v = np.linalg.eigh(cov)                                                 # ascending
    axis = v[:, :, 2]
    z = np.einsum("ti,ti->t", d, axis)
    r = np.linalg.norm(d - z[:, None] * axis, axis=1)
    return z, r, w[:, 2], np.sqrt(w[:, 0] * w[:, 1])


def _frame_log_likelihood(length: float | np.ndarray, z: np.ndarray, r: np.ndarray,
                          var_z: np.ndarray, var_r: np.ndarray, kappas: np.ndarray) -> np.ndarray:
    """``(T, K)`` log-density of each frame's bone for a ``length`` (one, or one a frame
    ``(T,)``) and each Watson concentration of ``kappas``: ``N(d; L u, S)`` integrated
    over the bone's direction ``u``, its azimuth about the noise's long axis in closed
    form (the von Mises integral, ``I_0``), ``c = cos`` of its angle to the axis by
    Gauss-Legendre quadrature on pieces cut where the integrand peaks (``c = z / L``
    along the axis, ``c = +-sqrt(1 - r^2 / L^2)`` across it; the pieces of zero width,
    cuts clipped to ``+-1``, left out)."""
    from scipy.special import i0e

    T = len(z)
    length = np.broadcast_to(np.asarray(length, dtype=float), (T,))
    sz, sr = np.sqrt(var_z), np.sqrt(var_r)
    cz = z / length
    cr = np.sqrt(np.clip(1.0 - (r / length) ** 2, 0.0, 1.0))
    wr = np.clip(sr * np.sqrt(np.clip(1.0 - cr ** 2, 1e-6, 1.0)) / (length * np.maximum(cr, 1e-3)),
                 0.0, 2.0)
    cuts = [np.full(T, -1.0), np.full(T, 1.0), np.zeros(T), np.full(T, -0.1), np.full(T, 0.1)]
    cuts += [cz + f * sz / length for f in (-6.0, -2.0, 2.0, 6.0)]
    cuts += [g * cr + f * wr for g in (-1.0, 1.0) for f in (-6.0, -2.0, 0.0, 2.0, 6.0)]
    cuts = np.sort(np.clip(np.stack(cuts, axis=1), -1.0, 1.0), axis=1)            # (T, P)
    half = 0.5 * (cuts[:, 1:] - cuts[:, :-1])
    mid = 0.5 * (cuts[:, 1:] + cuts[:, :-1])
    wide = half > 0                          # every row has one: its cuts span [-1, 1]
    row = np.nonzero(wide)[0]                                                     # (M,)
    starts = np.searchsorted(row, np.arange(T))
    half, mid = half[wide][:, None], mid[wide][:, None]
    c = mid + half * _GL_NODES                                                    # (M, 4)
    w = half * _GL_WEIGHTS
    L, zm, rm = length[row][:, None], z[row][:, None], r[row][:, None]
    vz, vr = var_z[row][:, None], var_r[row][:, None]
    s = L * np.sqrt(np.clip(1.0 - c * c, 0.0, 1.0))
    with np.errstate(divide="ignore"):
        log_f = (np.log(w) - (zm - L * c) ** 2 / (2.0 * vz) - (rm - s) ** 2 / (2.0 * vr)
                 + np.log(i0e(rm * s / vr)))
    # (reductions over the four nodes column by column: numpy's along a length-4 axis
    # cost ten times as much)
    top = np.maximum.reduceat(np.maximum(np.maximum(log_f[:, 0], log_f[:, 1]),
                                         np.maximum(log_f[:, 2], log_f[:, 3])), starts)
    prior = _watson_weights(c * c, kappas)                                        # (K, M, 4)
    prior *= np.exp(log_f - top[row][:, None])
    piece = prior[..., 0] + prior[..., 1] + prior[..., 2] + prior[..., 3]          # (K, M)
    dens = np.add.reduceat(piece, starts, axis=1).T                               # (T, K)
    with np.errstate(divide="ignore"):
        return (np.log(dens) + (top - 0.5 * np.log(2.0 * np.pi * var_z)
                                - np.log(2.0 * np.pi * var_r))[:, None]
                + np.maximum(kappas, 0.0) - _log_watson_norm(kappas))


def _stack_groups(groups: list[tuple[np.ndarray, ...]], frames: int | None = None
                  ) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """The frames of ``groups`` (each ``(z, r, var_z, var_r, log_out)``) end to end, at
    most ``frames`` of each (evenly spread), and where each group starts ``(G,)``."""
    parts = []
    for group in groups:
        n = len(group[0])
        if frames is not None and n > frames:
            keep = np.linspace(0, n - 1, frames).round().astype(int)
            group = tuple(v[keep] for v in group)
        parts.append(group)
    starts = np.cumsum([0] + [len(g[0]) for g in parts[:-1]])
    return tuple(np.concatenate(v) for v in zip(*parts)), starts


def _profile_log_likelihood(lengths: float | np.ndarray,
                            stacked: tuple[tuple[np.ndarray, ...], np.ndarray],
                            outlier_rate: float) -> float | np.ndarray:
    """The log-likelihood at each of ``lengths`` (one, or ``(C,)``: one call for all) of
    every group's frames (:func:`_stack_groups`), each group at its own best Watson
    concentration (:data:`WATSON_KAPPAS`), each frame mixed with the outlier density."""
    (z, r, var_z, var_r, log_out), starts = stacked
    C, n = np.size(lengths), len(z)
    inlier = _frame_log_likelihood(np.repeat(np.asarray(lengths, dtype=float).ravel(), n),
                                   np.tile(z, C), np.tile(r, C), np.tile(var_z, C),
                                   np.tile(var_r, C), WATSON_KAPPAS)
    mixed = np.logaddexp(np.log1p(-outlier_rate) + inlier,
                         np.log(outlier_rate) + np.tile(log_out, C)[:, None])
    per_group = np.add.reduceat(mixed.reshape(C, n, -1), starts, axis=1)        # (C, G, K)
    total = per_group.max(axis=2).sum(axis=1)
    return float(total[0]) if np.ndim(lengths) == 0 else total


def integrated_bone_lengths(rig: Rig, points: np.ndarray, used: np.ndarray,
                            planes: list[tuple[np.ndarray, float]], pairs: np.ndarray,
                            pixel_sigma: float, partners: np.ndarray | None = None,
                            outlier_rate: float = BONE_OUTLIER_RATE,
                            min_frames: int = 10) -> np.ndarray:
    """``(B,)`` bone lengths from noisy triangulated joints, free of the curvature bias.

    A bone ``d = X_a - X_b`` is measured in each frame with the noise of its two joints'
    triangulations, ``S = Sigma_a + Sigma_b``
    (:func:`~mirrorgraph.geometry.triangulation_covariance`): where their rays meet at a
    small angle ``S`` is long along the line of sight and ``|d|`` is decimetres too long
    on average (:func:`bone_curvature_bias`). The length ``L`` maximises the likelihood
    of every frame's ``d`` with the bone's direction ``u`` in each frame integrated out,
    ``p(d | L, kappa) = int N(d; L u, S) W(u; kappa) du`` (the integrated likelihood of a
    nuisance parameter: Berger, Liseo and Wolpert, *Statistical Science* 14, 1999), under
    a Watson prior about the noise's long axis ``a``, ``W(u) ~ exp(kappa (u . a)^2)``
    (Mardia and Jupp, *Directional Statistics*, 2000, sec. 9.4.2), whose concentration
    is the likelihood's own maximum for each bone (type-II maximum likelihood): a bone
    that stays across the line of sight takes a girdle, one that turns every way the
    uniform sphere. Frames of near-parallel rays tell the length by the bone's extent
    across the line of sight and hardly by its depth, where a moment estimate (the mean
    of ``|d|^2 - tr S``) takes their heavy depth tail, and a detector's per-label bias
    turned into depth, as length. Each frame is mixed with an outlier density
    (:data:`BONE_OUTLIER_RATE`); bones ``b`` and ``partners[b]`` (left and right) share
    one length, each with its own concentration; at most :data:`LIKELIHOOD_FRAMES` frames
    of each, spread over the clip, are evaluated. A grid of lengths (a quarter to twice
    the median measured one) on :data:`GRID_FRAMES` of them brackets the peak, then
    found on all of them (Brent's method, to ``1e-3`` of the length).

    Args:
        points: ``(T, J, 3)`` joints triangulated from the views (not pulled by priors);
            used: ``(T, J)`` bool.
        planes: ``(n, d)`` per mirror; pairs: ``(B, 2)`` joint indices.
        pixel_sigma: pixel noise, px.
        partners: ``(B,)`` the row of each bone's left/right partner among ``pairs``,
            ``-1`` for none; ``None``: every bone alone.
        outlier_rate: the frames' outlier share of the mixture.
        min_frames: frames a bone needs.

    Returns:
        The lengths in the points' unit; NaN for a bone seen in under ``min_frames``
        frames whose partner is not either.
    """
    from scipy.optimize import minimize_scalar

    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    masks = [np.asarray(v.mask, bool) & used for v in rig.views]
    cov = triangulation_covariance(view_projections(rig, None, planes), points, masks,
                                   pixel_sigma)                                  # (T, J, 3, 3)
    pts = np.asarray(points, dtype=float)
    groups: list[tuple[np.ndarray, ...] | None] = []
    typical = np.full(len(pairs), np.nan)
    for b, (i, j) in enumerate(pairs):
        d, s = pts[:, i] - pts[:, j], cov[:, i] + cov[:, j]
        ok = np.isfinite(d).all(1) & np.isfinite(s).all((1, 2)) & (np.linalg.norm(d, axis=1) > 0)
        if np.count_nonzero(ok):
            ok[ok] = np.linalg.eigvalsh(s[ok])[:, 0] > 0
        if np.count_nonzero(ok) < min_frames:
            groups.append(None)
            continue
        d, s = d[ok], s[ok]
        if len(d) > LIKELIHOOD_FRAMES:
            keep = np.linspace(0, len(d) - 1, LIKELIHOOD_FRAMES).round().astype(int)
            d, s = d[keep], s[keep]
        typical[b] = float(np.median(np.linalg.norm(d, axis=1)))
        radius = 5.0 * typical[b]
        log_out = np.full(len(d), -np.log(4.0 / 3.0 * np.pi * radius ** 3))
        groups.append((*_depth_frame(d, s), log_out))
    partners = (np.full(len(pairs), -1) if partners is None
                else np.asarray(partners, dtype=int))
    out = np.full(len(pairs), np.nan)
    for b in range(len(pairs)):
        if np.isfinite(out[b]):
            continue
        members = [b] + ([int(partners[b])] if partners[b] >= 0 else [])
        data = [groups[m] for m in members if groups[m] is not None]
        if not data:
            continue
        scale = float(np.nanmedian(typical[members]))
        grid = scale * np.geomspace(0.25, 2.0, 10)
        stacked = _stack_groups(data)
        x = None
        for frames in (GRID_FRAMES, None):
            # the grid on a spread subsample finds the peak's bracket; the bracket's
            # edge (a peak the subsample placed a grid step off) takes the full grid
            g = int(np.argmax(_profile_log_likelihood(grid, _stack_groups(data, frames),
                                                      outlier_rate)))
            lo, hi = grid[max(g - 1, 0)], grid[min(g + 1, len(grid) - 1)]
            best = minimize_scalar(lambda v: -_profile_log_likelihood(v, stacked, outlier_rate),
                                   bounds=(lo, hi), method="bounded",
                                   options={"xatol": 1e-3 * scale})
            x = float(best.x)
            edge = 2e-3 * scale
            if (x - lo > edge or g == 0) and (hi - x > edge or g == len(grid) - 1):
                break
        out[members] = x
    return out
