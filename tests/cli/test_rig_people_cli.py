"""``mirrorgraph calibrate-rig --people``: every person's 3D motion from a rig."""

from __future__ import annotations

import json

import numpy as np

from mirrorgraph.cli import main
from mirrorgraph.synth.rig_people import make_rig_people, write_rig_people


def test_calibrate_rig_every_person(tmp_path, capsys):
    rig = make_rig_people(3, 2, frames=40, seed=6)
    path = write_rig_people(rig, tmp_path / "rig", subject_height=1.75)
    code = main(["calibrate-rig", str(path), "--out", str(tmp_path / "c.toml"),
                 "--people", "all", "--joints3d", str(tmp_path / "people.npz"),
                 "--view", str(tmp_path / "r.rrd")])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "people: 2 in the one graph" in out.out
    doc = json.loads((tmp_path / "c.json").read_text())
    assert doc["refinement"]["people"]["count"] == 2
    with np.load(tmp_path / "people.npz") as f:
        assert f["joints3d"].shape == (2, 40, 25, 3)
        assert list(f["people"]) == ["P0", "P1"]
        assert str(f["unit"]) == "m"
    # the view draws every person: more joints in a frame than one person has
    from rerun.chunk import RrdReader
    points = {}
    for chunk in RrdReader(tmp_path / "r.rrd").stream().to_chunks():
        if chunk.entity_path == "/world/person/joints":
            rb = chunk.to_record_batch()
            col = [n for n in rb.schema.names if n.endswith("positions")]
            if col and "frame" in rb.schema.names:
                for f, v in zip(rb.column("frame").to_pylist(), rb.column(col[0]).to_pylist()):
                    points[f] = len(v)
    assert points and max(points.values()) > 25, points
    code = main(["calibrate-rig", str(path), "--out", str(tmp_path / "d.toml"),
                 "--people", "one", "--joints3d", str(tmp_path / "one.npz"), "--quiet"])
    assert code == 0
    with np.load(tmp_path / "one.npz") as f:
        assert f["joints3d"].shape == (40, 25, 3)
    assert json.loads((tmp_path / "d.json").read_text())["refinement"]["people"] == {
        "mode": "one", "count": 1}
    code = main(["calibrate-rig", str(path), "--out", str(tmp_path / "e.toml"),
                 "--people", "several"])
    assert code == 2
    assert "--people" in capsys.readouterr().err
