"""The public API: ``mirrorgraph.__all__`` is true (every name resolves, lazily where its
module pulls GTSAM or an extra), the *Python API* page's table (``docs/api.md``) lists
exactly those names, and the notebook uses only them (and :mod:`mirrorgraph.synth`)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import mirrorgraph as mg

ROOT = Path(__file__).resolve().parent.parent


def test_every_public_name_resolves_and_dir_lists_it():
    for name in mg.__all__:
        assert getattr(mg, name) is not None, name
    assert set(mg.__all__) <= set(dir(mg))
    assert len(set(mg.__all__)) == len(mg.__all__)


def test_the_api_page_table_is_the_public_api():
    text = (ROOT / "docs" / "api.md").read_text()
    section = text.split("# Python API", 1)[1].split("```python", 1)[0]
    rows = [line.split("|")[1] for line in section.splitlines() if line.startswith("| `")]
    named = {m for row in rows for m in re.findall(r"`([A-Za-z_]+)[`(]", row)}
    public = set(mg.__all__) - {"__version__"}
    assert named == public, (named - public, public - named)


def test_the_notebook_imports_only_public_names():
    nb = json.loads((ROOT / "notebooks" / "walkthrough.ipynb").read_text())
    code = "".join("".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code")
    imports = set(re.findall(r"^\s*(?:from|import) (mirrorgraph[\w.]*)", code, re.M))
    assert imports <= {"mirrorgraph", "mirrorgraph.synth"}, imports
    used = set(re.findall(r"\bmg\.(\w+)", code))
    assert used <= set(mg.__all__), used - set(mg.__all__)


def test_the_two_front_ends_take_one_options_object_and_name_their_callbacks_alike(tmp_path):
    """One :class:`CalibrateOptions` for both front ends (the rig's old keywords still work,
    with a DeprecationWarning, and mean the same); ``progress`` gets the step names,
    ``iteration_progress`` (iteration, error), in ``calibrate`` and ``calibrate_rig`` alike."""
    import inspect

    from mirrorgraph.synth import make_rig, make_scene, write_rig

    one = inspect.signature(mg.calibrate).parameters
    rig = inspect.signature(mg.calibrate_rig).parameters
    assert one["options"].annotation == rig["options"].annotation
    for name in ("progress", "iteration_progress"):
        assert str(one[name].annotation) == str(rig[name].annotation), name
    small = write_rig(make_rig("2cams1mirror", frames=30, seed=2), tmp_path / "small")
    new = mg.calibrate_rig(small, mg.CalibrateOptions(subject_height=1.7, seed=3))
    with pytest.warns(DeprecationWarning, match="CalibrateOptions"):
        old = mg.calibrate_rig(small, subject_height=1.7, seed=3)
    assert np.array_equal(new.cameras[1].pose, old.cameras[1].pose)
    with pytest.raises(TypeError, match="frames"):
        mg.calibrate_rig(small, frames=3)

    calls: dict[str, list] = {"steps": [], "iterations": []}
    scene = make_scene(frames=60, seed=1)
    mg.calibrate(scene.detections, scene.intrinsics, progress=calls["steps"].append,
                 iteration_progress=lambda i, e: calls["iterations"].append((i, e)))
    path = write_rig(make_rig("2cams1mirror", frames=40, seed=0), tmp_path)
    mg.calibrate_rig(path, progress=calls["steps"].append,
                     iteration_progress=lambda i, e: calls["iterations"].append((i, e)))
    assert calls["steps"] and all(isinstance(s, str) for s in calls["steps"])
    assert any("refin" in s for s in calls["steps"])
    assert calls["iterations"] and all(isinstance(i, int) and float(e) >= 0
                                       for i, e in calls["iterations"])


def test_a_missing_extra_is_one_error_type(capsys):
    """Every optional import goes through errors.require_extra: a MissingExtraError, both
    an ImportError and a MirrorgraphError, naming what needs it and the install line."""
    from mirrorgraph.errors import MissingExtraError, require_extra

    with pytest.raises(MissingExtraError) as info:
        require_extra("no_such_module_mg25", "plot", "the report", what="matplotlib")
    err = info.value
    assert isinstance(err, ImportError) and isinstance(err, mg.MirrorgraphError)
    assert not isinstance(err, mg.InputError)
    assert err.name == "no_such_module_mg25" and err.extra == "plot"
    assert str(err) == ("the report needs matplotlib: pip install 'mirrorgraph[plot]' "
                        "(in a clone: pip install -e '.[plot]')")
    assert require_extra("json", "none", "x").dumps([]) == "[]"


def test_the_missing_extras_raise_it(monkeypatch):
    import sys

    from mirrorgraph.batch import run_batch
    from mirrorgraph.errors import MissingExtraError
    from mirrorgraph.io.c3d_writer import require_c3d
    from mirrorgraph.io.motion import check_motion_path
    from mirrorgraph.report import require_matplotlib
    from mirrorgraph.viewer.recording import require_rerun

    for module in ("matplotlib", "rerun", "c3d", "dask.distributed"):
        monkeypatch.setitem(sys.modules, module, None)      # import raises ImportError
    for call, text in ((require_matplotlib, "the report needs matplotlib: pip install "
                                            "'mirrorgraph[plot]'"),
                       (require_rerun, "the viewer needs the Rerun SDK: pip install "
                                       "'mirrorgraph[view]'"),
                       (require_c3d, "writing .c3d needs the c3d package: pip install "
                                     "'mirrorgraph[c3d]'"),
                       (lambda: check_motion_path("a.c3d", metric=True), "writing .c3d"),
                       (lambda: run_batch([object()]), "mirrorgraph batch needs Dask: pip "
                                                       "install 'mirrorgraph[batch]'")):
        with pytest.raises(MissingExtraError) as info:
            call()
        assert str(info.value).startswith(text)
