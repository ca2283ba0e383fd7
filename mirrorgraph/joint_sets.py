"""The ``joints`` option of ``calibrate`` and ``calibrate-rig``: which keypoints enter the graph.

One spec, the same words in both commands (``--joints`` of ``mirrorgraph calibrate``,
``joints =`` of a rig file):

============ =================================================== =====================
spec         direct views (camera - camera pairs)                views through mirrors
============ =================================================== =====================
``auto``     every keypoint                                      the limbs
``limbs``    the limbs                                           the limbs
``all``      every keypoint                                      every keypoint
names        the named joints (at least 4)                       the same
============ =================================================== =====================

"The limbs" are the skeleton's calibration joints
(:attr:`mirrorgraph.skeletons.Skeleton.calibration_joints`: shoulders to wrists, hips
to ankles, and neck / mid-hip where the layout has them). MirrorCalib leaves face,
hands and feet out: small and often hidden, above all in a reflection seen from
farther away. With one mirror every pair the graph uses is seen through the mirror,
so ``auto`` (the default) is the limbs; the keypoints left out are triangulated with
the solved mirror afterwards (:mod:`mirrorgraph.completion`), so ``--joints3d``
holds every keypoint whatever the spec.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .errors import InputError

__all__ = ["JOINT_SETS", "MIN_JOINTS", "resolve_joints", "mirror_joints"]

#: Named joint sets (see the module docstring). Measured on the 4-camera rig (10 seeds,
#: 300 frames, 4 px): every keypoint in the direct views (``auto``) halves the side
#: cameras' rotation std and puts 9 seeds of 10 within 0.5 deg and 2 cm
#: (scale-aligned), 8 with the limbs.
JOINT_SETS = ("auto", "limbs", "all")

#: Fewest joints a list of names may hold: the pairing scores a candidate pair by the
#: median over at least 4 shared joints (:class:`mirrorgraph.initial.pairing.PairingOptions`).
MIN_JOINTS = 4


def _words(spec: str | Sequence[str] | None) -> str | list[str] | None:
    """``None``, a set's name, or a list of joint names (from a comma-separated string,
    or a sequence; a one-element sequence holding a set's name is that set, which is how
    a command line's ``--joints all`` split at commas arrives)."""
    if spec is None:
        return None
    if isinstance(spec, str):
        spec = [n.strip() for n in spec.split(",") if n.strip()]
    else:
        spec = [str(n).strip() for n in spec if str(n).strip()]
    if not spec:
        return None
    if len(spec) == 1 and spec[0].lower() in JOINT_SETS:
        return spec[0].lower()
    return spec


def resolve_joints(skeleton, spec: str | Sequence[str] | None, source: str | None = None
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Joint indices of a joint spec, for the direct views and for the views through mirrors.

    Args:
        skeleton: the layout (:class:`mirrorgraph.skeletons.Skeleton`).
        spec: ``None`` / ``""`` / ``"auto"``, ``"limbs"``, ``"all"``, a comma-separated
            string or a sequence of joint names (the same joints in every view); a
            one-element sequence holding a set's name counts as that name.
        source: the file the spec came from, for messages.

    Returns:
        ``(direct (k,), mirror (m,))`` sorted int joint indices.

    Raises:
        InputError: an unknown joint name or fewer than :data:`MIN_JOINTS` names (one
            line listing the set names and the layout's joints, field ``joints``).
    """
    limbs = np.asarray(skeleton.calibration_joints, dtype=int)
    every = np.arange(skeleton.num_joints)
    words = _words(spec)
    if words is None or words == "auto":
        return every, limbs
    if words == "limbs":
        return limbs, limbs
    if words == "all":
        return every, every
    missing = [n for n in words if not skeleton.has(n)]
    chosen = sorted({skeleton.index(n) for n in words if skeleton.has(n)})
    if missing or len(chosen) < MIN_JOINTS:
        raise InputError(("unknown joint(s) " + ", ".join(missing) if missing else
                          f"needs at least {MIN_JOINTS} joints, got {len(chosen)}")
                         + f"; use auto, limbs, all, or names of {skeleton.name}: "
                         + ", ".join(skeleton.joints), source=source, field="joints")
    chosen_arr = np.array(chosen, dtype=int)
    return chosen_arr, chosen_arr


def mirror_joints(skeleton, spec: str | Sequence[str] | None, source: str | None = None
                  ) -> np.ndarray:
    """``(k,)`` sorted joint indices a single-mirror calibration uses for a spec.

    Every pair of one mirror is seen through the mirror, so this is the mirror half of
    :func:`resolve_joints`: ``auto`` and ``limbs`` give the calibration joints, ``all``
    every keypoint, names the named joints.
    """
    return resolve_joints(skeleton, spec, source)[1]
