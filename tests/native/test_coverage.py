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
    # The region's radius, as the report states it for a held-out view: the one the pick used.
    eye = np.asarray(user.camera_position)
    assert coverage.region_radius(scene, eye) == pytest.approx(cov.radius[0])
    assert 0.5 < cov.radius[0] < 2.0  # the free distance inside a 2 m box
    assert coverage.region_radius(scene, eye, 0.3) == pytest.approx(0.3)


def test_the_poses_traced_together_see_what_each_sees_alone(scene):
    """``pick`` traces every candidate's probe in one call: each pose's hits, positions,
    normals, triangles and depths are the ones its own trace gives, bit for bit, and
    ``Scene.intersect`` (parallel) answers as ray-by-ray calls do."""
    poses = [
        coverage.Pose(np.array(eye), np.array(f), np.array(u))
        for eye in ([0.0, 0.0, 1.0], [0.5, -0.3, 0.7])
        for f, u in coverage.FACES
    ]
    together = coverage._hits_of(scene, BOX_V[BOX_T], poses, 12)
    assert len(together) == len(poses)
    for pose, got in zip(poses, together, strict=True):
        alone = coverage._hits(scene, BOX_V[BOX_T], pose, 12)
        assert got[0].any()
        for a, b in zip(alone, got, strict=True):
            np.testing.assert_array_equal(a, b)
    dirs, _ = poses[3].rays(12)
    origins = np.ascontiguousarray(np.broadcast_to(poses[3].eye.astype(np.float32), dirs.shape))
    t, tri, bary = scene.intersect(origins, dirs)
    for k in (0, 17, 143):
        t1, tri1, bary1 = scene.intersect(origins[k : k + 1], dirs[k : k + 1])
        assert (t1[0], tri1[0]) == (t[k], tri[k]) and np.array_equal(bary1[0], bary[k])
    assert bary.shape == (len(dirs), 2)
    assert scene.intersect(origins[:0], dirs[:0])[2].shape == (0, 2)


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


def room_with_window() -> tuple[vplace.Scene, np.ndarray]:
    """The box of ``box_mesh`` whose -y wall has a window (x in [-0.4, 0.4], z in [0.6, 1.4]),
    a sun shining in through it; and the (T, 3, 3) corners of its triangles."""
    v, _ = box_mesh()
    # The -y wall (the box's last quad) goes; four panes around the hole come.
    quads = [v[4 * q : 4 * q + 4].tolist() for q in range(5)]
    y = -1.0
    panes = [(-1, -0.4, 0, 2), (0.4, 1, 0, 2), (-0.4, 0.4, 0, 0.6), (-0.4, 0.4, 1.4, 2)]
    for x0, x1, z0, z1 in panes:
        quads.append([[x0, y, z0], [x0, y, z1], [x1, y, z1], [x1, y, z0]])
    verts = np.array([p for q in quads for p in q], dtype=np.float32)
    tris = np.array(
        [[b, b + 1, b + 2] for b in range(0, len(verts), 4)]
        + [[b, b + 2, b + 3] for b in range(0, len(verts), 4)],
        dtype=np.uint32,
    )
    ids = np.zeros(len(tris), dtype=np.uint32)
    albedo = np.array([[0.5, 0.5, 0.5]], dtype=np.float32)
    sun = vplace.Light.sun([0.0, 0.8, -0.6], [3.0, 3.0, 3.0])
    return vplace.Scene(verts, tris, ids, albedo, [sun]), verts[tris]


def test_no_view_stands_beyond_the_rooms_window():
    # A camera by the window, looking into the room: the ray it casts out of the window escapes.
    # A region point along it stood outside the room and saw the wall's sunlit outer face, which
    # no camera in the room sees, and the layout spent VPLs on it (a flat's sunlit facade took
    # 49 of 256). Every coverage and held-out view now stands inside.
    scene, corners = room_with_window()
    pose = coverage.Pose(np.array([0.0, -0.6, 1.0]), np.array([0, 1.0, 0]), np.array([0, 0, 1.0]))
    target = vplace.uniform_vpls(scene, 64, bounces=vplace.MAX_BOUNCES)
    user = coverage.coverage_view(scene, corners, pose, 24, target, name="user camera")
    assert coverage.enclosed(scene, pose.eye.astype(np.float32))
    cov = coverage.cover(scene, corners, [user], coverage.Region(count=8, size=16))
    assert cov.poses
    inside = [bool(p.eye[1] > -1.0) for p in cov.poses]
    assert all(inside), [p.eye for p in cov.poses]
    for seed in range(8):
        for p in coverage.held_out_poses(scene, pose.eye, pose.forward, 3, seed=seed):
            assert p.eye[1] > -1.0, p.eye
    # Outdoors (most rays escape), a ray that escapes still reaches the region's radius.
    assert coverage.reach(2.0, float("inf"), inside=False) == 2.0
    assert coverage.reach(2.0, float("inf"), inside=True) == 0.0
    assert coverage.reach(2.0, 1.0, inside=True) == coverage.WALL_MARGIN * 1.0


def perspective(near: float, far: float, sx: float = 1.0, sy: float = 1.0) -> np.ndarray:
    """An OpenGL perspective projection (Blender's) of clip start ``near`` and end ``far``."""
    a, b = (far + near) / (near - far), 2 * far * near / (near - far)
    return np.array([[sx, 0, 0, 0], [0, sy, 0, 0], [0, 0, a, b], [0, 0, -1.0, 0]])


def test_a_views_eye_is_the_centre_of_its_near_clip_plane():
    eye, forward = np.array([1.0, -2.0, 0.5]), np.array([0.0, 0.6, 0.8])
    pose = coverage.Pose(eye, forward, np.array([0.0, 0.0, 1.0]))
    assert coverage.view_eye(pose.world_to_clip()) == pytest.approx(
        eye + coverage.NEAR * forward, abs=1e-5
    )
    f, right, up = pose.basis()
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, up, -f
    view[:3, 3] = -view[:3, :3] @ eye
    n, far = 1.5, 40.0  # a clip start of 1.5: that far along the axis, whatever the lens
    lens = perspective(n, far, 3.0, 2.0)
    assert coverage.view_eye(lens @ view) == pytest.approx(eye + n * forward, abs=1e-4)
    c, d = -2 / (far - n), -(far + n) / (far - n)
    ortho = np.array([[0.2, 0, 0, 0], [0, 0.2, 0, 0], [0, 0, c, d], [0, 0, 0, 1.0]])
    assert coverage.view_eye(ortho @ view) == pytest.approx(eye + n * forward, abs=1e-4)


def test_a_view_gives_back_its_world_to_clip_matrix(scene):
    pose = coverage.Pose(np.array([0.0, 0.0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 0, 1.0]))
    m = user_view(scene).world_to_clip
    assert m.dtype == np.float32 and m.shape == (4, 4)
    assert m == pytest.approx(pose.world_to_clip().astype(np.float32), rel=1e-6, abs=1e-7)


def test_a_camera_stands_past_its_clip_start_only_where_that_passes_a_wall(scene):
    def clip(eye: list[float], near: float) -> np.ndarray:
        """World-to-clip of a camera at ``eye`` looking along +x with clip start ``near``."""
        view = np.array([[0, -1.0, 0, 0], [0, 0, 1.0, 0], [-1.0, 0, 0, 0], [0, 0, 0, 1.0]])
        view[:3, 3] = -view[:3, :3] @ np.array(eye)
        return perspective(near, 50.0) @ view

    # Outside the box's -x wall, its clip start 1 past it: it stands where its view begins.
    eye = coverage.camera_eye(scene, [-1.5, 0.2, 0.9], clip([-1.5, 0.2, 0.9], 1.0))
    assert eye == pytest.approx([-0.5, 0.2, 0.9], abs=1e-5)
    # Inside, a clip start that passes nothing: its own position.
    eye = coverage.camera_eye(scene, [0.0, 0.0, 1.0], clip([0.0, 0.0, 1.0], 0.5))
    assert eye.tolist() == [0.0, 0.0, 1.0]
