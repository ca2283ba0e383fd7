"""The commands of the CLI: which module of :mod:`mirrorgraph.cli` defines each, and its
one-line help.

``mirrorgraph --help`` lists every command from here, and a run builds the options of
its own command only (:func:`mirrorgraph.cli.build_parser`): the other modules, and
what they import (the synthetic scenes, the video package, the viewer), are not
imported. Each module's ``add_parsers`` takes its commands' help from :data:`HELP`.
"""

from __future__ import annotations

__all__ = ["COMMANDS", "HELP", "MODULES"]

#: command -> (module of mirrorgraph.cli that adds and runs it, its one-line help);
#: in the order ``mirrorgraph --help`` lists them.
COMMANDS: dict[str, tuple[str, str]] = {
    "calibrate": ("calibrate", "calibrate the mirror from 2D keypoints"),
    "synth": ("synth", "write a synthetic mirror scene with ground truth"),
    "demo": ("synth", "run the whole pipeline on an embedded synthetic scene"),
    "export": ("report", "write the real and virtual camera for Pose2Sim / aniposelib"),
    "report": ("report", "figures of a calibration: epipole, residuals, 3D view, "
                         "bone lengths, uncertainty"),
    "batch": ("batch", "calibrate many recordings in parallel (Dask)"),
    "calibrate-rig": ("rig", "calibrate several cameras and mirrors from the people in view"),
    "synth-rig": ("rig", "write a synthetic rig with ground truth"),
    "detect": ("video", "detect every person's 2D keypoints in a video (offline)"),
    "view": ("view", "look at a calibration and its 3D motion in Rerun"),
    "live": ("live", "calibrate while the video streams: 3D joints frame by frame "
                     "(JSON lines)"),
}

#: command -> its one-line help.
HELP: dict[str, str] = {name: help_ for name, (_, help_) in COMMANDS.items()}

#: the modules, in the order of their first command.
MODULES: tuple[str, ...] = tuple(dict.fromkeys(module for module, _ in COMMANDS.values()))
