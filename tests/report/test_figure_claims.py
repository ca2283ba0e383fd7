"""What each figure claims, checked as a reader would (#27): like compared with like,
ellipses one can see, legends that say what the lines do and cover no data."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

pytest.importorskip("matplotlib")

import mirrorgraph as mg  # noqa: E402
from mirrorgraph.report import figures, report_data, require_matplotlib  # noqa: E402
from mirrorgraph.report.video import legend_corner  # noqa: E402
from mirrorgraph.synth import make_scene  # noqa: E402


@pytest.fixture(scope="module")
def data():
    scene = make_scene(frames=120, seed=11)
    run = mg.calibrate(scene.detections, scene.intrinsics,
                       mg.CalibrateOptions(subject_height=scene.subject_height))
    return report_data(run)


def test_reprojection_compares_like_with_like(data):
    """Before and after are the same construction (each pair triangulated on its own),
    only the mirror differs; the graph's joints are a third, labelled series."""
    plt = require_matplotlib()
    fig = figures.residuals(data)
    labels = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    assert len(labels) == 3
    assert "initial mirror, pairs triangulated" in labels[0]
    assert "refined mirror, pairs triangulated" in labels[1]
    assert "graph's 3D joints" in labels[2]
    m = data.inlier
    assert np.median(data.reproj_after[m]) <= 1.01 * np.median(data.reproj_before[m])
    plt.close(fig)


def test_an_elongated_ellipse_is_drawn_in_its_own_axes(data):
    """A 50:1 epipole covariance (a mirror seen nearly edge-on) is no sliver: both of its
    axes fill a good part of the plot."""
    plt = require_matplotlib()
    a = np.radians(25.0)
    V = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    cov = V @ np.diag([250.0 ** 2, 5.0 ** 2]) @ V.T
    fig = figures.uncertainty(dataclasses.replace(data, epipole_cov=cov,
                                                  marginal_epipole_cov=None))
    ax = fig.axes[0]
    one_sigma = ax.get_lines()[0].get_xydata()
    extent = np.ptp(one_sigma, axis=0)
    span = np.array([np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim())])
    assert np.all(extent / span > 0.15), (extent, span)      # at equal scales: 10 / 1800
    assert "major axis" in ax.get_xlabel() and "stretched" in ax.get_title()
    plt.close(fig)
    fig = figures.uncertainty(dataclasses.replace(data, epipole_cov=np.diag([4.0, 3.0])))
    # a round one keeps the image's axes
    assert fig.axes[0].get_xlabel() == "x (px)"
    plt.close(fig)


def test_frames_needed_legend_says_what_the_lines_do(data):
    plt = require_matplotlib()
    fig = figures.sensitivity(data)
    ax = fig.axes[3]
    text = " ".join(t.get_text() for t in ax.get_legend().get_texts())
    assert "a bias does not fall" not in text and "floor" in text
    fn = data.sensitivity["frames_needed"]
    iid = np.asarray(fn["iid_rotation_std_deg"])
    n = np.asarray(fn["frames"], float)
    # the iid line is what its label says: 1/sqrt(frames)
    np.testing.assert_allclose(iid * np.sqrt(n), iid[0] * np.sqrt(n[0]), rtol=1e-6)
    plt.close(fig)


def test_bone_lengths_count_what_falls_off_the_axes(data):
    plt = require_matplotlib()
    spiky = dataclasses.replace(data, bones_after=data.bones_after.copy())
    spiky.bones_after[5, 0] = 10 * np.nanmedian(data.bones_after[:, 0])
    fig = figures.bone_lengths(spiky)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any("1 off the axes" in t for t in labels), labels
    plt.close(fig)


def test_overlay_legend_avoids_the_people():
    """The person in the top-left corner, the reflection top-right: the legend goes to a
    bottom corner; with joints everywhere but the bottom right, there."""
    size, box = (1920, 1080), (230, 120)
    people = np.array([[100.0, 80], [200, 150], [1800, 60], [1700, 200], [np.nan, np.nan]])
    x, y = legend_corner(size, box, people)
    assert y > 500
    grid = np.stack(np.meshgrid(np.linspace(0, 1900, 20), np.linspace(0, 1000, 12)), -1)
    grid = grid.reshape(-1, 2)
    grid = grid[~((grid[:, 0] > 1500) & (grid[:, 1] > 800))]
    assert legend_corner(size, box, grid) == (1920 - 230 - 4, 1080 - 120 - 4)
