"""The initialisation: a first mirror (and a first rig) from the 2D keypoints alone.

* :mod:`.solvers` -- minimal and linear solvers (the reflective two-point and
  three-point solvers, the eight-point baselines), apart from
* :mod:`.ransac` -- the generic robust estimator that takes any of them (as PoseLib
  and COLMAP keep them);
* :mod:`.estimators` -- solvers + RANSAC for the mirror of one camera;
* :mod:`.pairing` -- which detection is the person and which their reflection, and
  their left/right labels;
* :mod:`.reflection_check` -- is the "reflection" a second person?
* :mod:`.relative` -- two-view initialisation of a rig (camera-camera, camera-mirror);
* :mod:`.rig` -- the spanning-tree chaining of a rig's pairs into one initial rig.

What follows the initialisation is the graph (:mod:`mirrorgraph.graph`), driven by the
runs of :mod:`mirrorgraph.pipelines`.
"""
