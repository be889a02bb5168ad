"""vplace.coverage: the coverage views of the region around a camera (no Blender)."""

import numpy as np
import pytest
import vplace
from test_layout import box_mesh, box_scene
from vplace import coverage, job

BOX_V, BOX_T = box_mesh()


@pytest.fixture(scope="module")
def scene() -> vplace.Scene:
    return box_scene()


def user_view(scene: vplace.Scene) -> vplace.View:
    """A camera at the box's centre looking at its +x wall (it sees one wall of six)."""
    pose = coverage.Pose(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))
    target = vplace.uniform_vpls(scene, 64, bounces=vplace.MAX_BOUNCES)
    return coverage.coverage_view(scene, BOX_V[BOX_T], pose, 24, target, name="user camera")


def test_coverage_views_see_what_the_camera_does_not(scene):
    user = user_view(scene)
    cov = coverage.cover(scene, BOX_V[BOX_T], [user], coverage.Region(count=4, size=16))
    assert 1 <= len(cov.views) <= 4
    assert cov.covered_after > cov.covered_before
    # None repeats the user's view: it would add nothing.
    assert not any(
        np.allclose(p.eye, [0, 0, 1]) and np.allclose(p.forward, [1, 0, 0]) for p in cov.poses
    )
    for view in cov.views:
        assert coverage.is_coverage(view) and view.has_indirect
        assert view.covered.all()  # a closed box: every ray hits a wall
        ind = view.indirect
        assert np.isfinite(ind).all() and (ind >= 0).all() and ind.mean() > 0
        # The traced G-buffer lies on the box's walls, its normals face the eye.
        pos = view.position.reshape(-1, 3)
        on_wall = (
            np.isclose(np.abs(pos[:, :2]), 1, atol=1e-3).any(1)
            | np.isclose(pos[:, 2], 0, atol=1e-3)
            | np.isclose(pos[:, 2], 2, atol=1e-3)
        )
        assert on_wall.all()
        to_eye = np.asarray(view.camera_position) - pos
        assert (np.sum(view.normal.reshape(-1, 3) * to_eye, axis=1) > 0).all()
    again = coverage.cover(scene, BOX_V[BOX_T], [user], coverage.Region(count=4, size=16))
    for a, b in zip(cov.views, again.views, strict=True):  # deterministic
        np.testing.assert_array_equal(a.indirect, b.indirect)


def test_the_fit_learns_from_the_captures_only(scene):
    user = user_view(scene)
    cov = coverage.cover(scene, BOX_V[BOX_T], [user], coverage.Region(count=2, size=16))
    settings = job.LayoutSettings(cell_px=8, feature_mode="all")
    with_cover = job.fit(scene, [user, *cov.views], settings)
    alone = job.fit(scene, [user], settings)
    assert with_cover.r2 == alone.r2


@pytest.mark.parametrize(
    ("region", "message"),
    [
        (coverage.Region(count=-1), "coverage views"),
        (coverage.Region(count=17), "coverage views"),
        (coverage.Region(radius=-1.0), "radius"),
        (coverage.Region(radius=float("nan")), "radius"),
        (coverage.Region(size=4), "at least 8"),
    ],
)
def test_bad_regions_are_refused(region, message):
    with pytest.raises(ValueError, match=message):
        region.validate()


def test_no_coverage_views_when_off(scene):
    cov = coverage.cover(scene, BOX_V[BOX_T], [user_view(scene)], coverage.Region(count=0))
    assert cov.views == [] and cov.poses == []


def test_held_out_poses_stay_in_the_region_and_look_elsewhere(scene):
    eye, forward = np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])
    poses = coverage.held_out_poses(scene, eye, forward, 5, seed=3)
    assert len(poses) == 5
    radius = coverage.REGION_FRACTION * coverage.free_distance(scene, eye.astype(np.float32))
    lo, hi = (np.asarray(b) for b in scene.bounds)
    for p in poses:
        moved = float(np.linalg.norm(p.eye - eye))
        assert 0.1 * radius <= moved <= coverage.HELD_OUT_REACH[1] * radius + 1e-6
        assert ((p.eye > lo) & (p.eye < hi)).all()  # inside the box
        f = p.forward / np.linalg.norm(p.forward)
        turn = np.degrees(np.arccos(np.clip(f @ forward, -1, 1)))
        assert coverage.HELD_OUT_TURN[0] - 1e-6 <= turn <= coverage.HELD_OUT_TURN[1] + 1e-6
        assert abs(f[2]) < 1e-9  # level, like the camera
    again = coverage.held_out_poses(scene, eye, forward, 5, seed=3)
    assert all(np.array_equal(a.eye, b.eye) for a, b in zip(poses, again, strict=True))
    other = coverage.held_out_poses(scene, eye, forward, 5, seed=4)
    assert not np.array_equal(poses[0].eye, other[0].eye)
    # Given a radius, the poses keep to it.
    near = coverage.held_out_poses(scene, eye, forward, 3, seed=3, radius=0.2)
    assert all(np.linalg.norm(p.eye - eye) <= 0.2 * coverage.HELD_OUT_REACH[1] + 1e-6 for p in near)
