"""The views of a job (DESIGN: Views): which cameras, at which frames, the capture renders.

A job lays out one set of lights for several views. :class:`ViewSet` says which:

- ``active``: the scene camera (the default);
- ``cameras``: scene cameras the user picks, by name;
- ``frames``: an animated camera (the scene camera) at the frames ``start, start + step, ...,
  end``;
- ``orbit``: ``count`` views around the scene camera: the camera turned about the world Z axis
  through a pivot ``radius`` metres in front of it (default: as far as the scene's centre), by
  angles spread evenly over ``[-angle, +angle]`` degrees; the scene camera itself is the first.

:func:`resolve` turns a view set into :class:`ViewSpec` objects (camera object, frame, name);
:func:`generated_cameras` makes the orbit's temporary camera objects and always removes them
again, so the user's file is left as it was.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import bpy
import numpy as np
from mathutils import Matrix, Vector

from ..errors import AddonError
from ..native import vplace
from .passes import camera_matrices

VIEW_MODES = ("active", "cameras", "frames", "orbit")
#: Custom property marking the temporary cameras of an orbit (removed after the capture).
ORBIT_MARKER = "vplace_orbit_camera"
#: Custom property marking the temporary camera of a coverage view rendered by Cycles.
COVERAGE_MARKER = "vplace_coverage_camera"


#: The most views one layout captures (the panel's orbit count is capped alike).
MAX_VIEWS = 64


@dataclass(frozen=True)
class ViewSet:
    """Which views a job captures (see the module docs)."""

    mode: str = "active"
    cameras: tuple[str, ...] = ()
    frame_start: int = 1
    frame_end: int = 1
    frame_step: int = 1
    orbit_count: int = 4
    #: From the camera to the orbit's pivot, scene units (metres at Unit Scale 1; the command
    #: line's metres are converted, `Job.in_scene_units`); 0: the distance to the scene's centre.
    orbit_radius: float = 0.0
    orbit_angle: float = 30.0
    #: Coverage views added for the region around these views (``vplace.coverage``; 0: none).
    #: Rendered (:attr:`render_coverage`), they are fitted as captures; traced, the layout
    #: places for them and the refit holds the VPLs that light what only they show.
    coverage: int = vplace.coverage.DEFAULT_COUNT
    #: The region's radius around each camera, scene units; 0: from the room the camera stands
    #: in.
    region_radius: float = 0.0
    #: Render the coverage views with Cycles (at the capture's samples, the region's ``size``
    #: pixels square) and fit them as captures (``capture.stage.rendered_coverage``), instead
    #: of tracing them with light-path VPLs as their indirect image: the default since stop 60,
    #: with the refit's bound on the scales (``vplace.job.REGION_MAX_SCALE``, ARCHITECTURE.md).
    render_coverage: bool = True

    def region(self) -> vplace.coverage.Region:
        """The region the coverage views stand for."""
        return vplace.coverage.Region(count=self.coverage, radius=self.region_radius)

    def validate(self) -> None:
        """Raises :class:`AddonError` for a view set no capture can run with."""
        if self.mode not in VIEW_MODES:
            raise AddonError(f"view mode must be one of {list(VIEW_MODES)}, got {self.mode!r}")
        if self.mode == "cameras" and not self.cameras:
            raise AddonError("choose at least one camera for the views")
        if self.mode == "frames" and (self.frame_step < 1 or self.frame_end < self.frame_start):
            raise AddonError(
                f"frames {self.frame_start}..{self.frame_end} step {self.frame_step}: the end "
                "must not come before the start and the step must be at least 1"
            )
        if self.mode == "orbit" and (self.orbit_count < 1 or self.orbit_radius < 0):
            raise AddonError("an orbit needs at least one view and a radius of 0 or more")
        if self.mode == "orbit" and not 0.0 <= self.orbit_angle <= 180.0:
            raise AddonError(f"an orbit turns by 0 to 180 degrees, got {self.orbit_angle:g}")
        count = {
            "cameras": len(set(self.cameras)),
            "frames": len(range(self.frame_start, self.frame_end + 1, max(self.frame_step, 1))),
            "orbit": self.orbit_count,
        }.get(self.mode, 1)
        if count > MAX_VIEWS:
            raise AddonError(
                f"{count} views is more than the {MAX_VIEWS} a layout takes (each is a Cycles "
                "capture): choose fewer"
            )
        try:
            self.region().validate()
        except ValueError as err:
            raise AddonError(str(err)) from None


@dataclass(frozen=True)
class ViewSpec:
    """One view to capture: a camera object, the frame to render it at, and a name."""

    name: str
    camera: bpy.types.Object
    frame: int | None = None


def _camera(name: str) -> bpy.types.Object:
    cam = bpy.data.objects.get(name)
    if cam is None or cam.type != "CAMERA":
        raise AddonError(f"the scene has no camera object named {name!r}")
    return cam


def _scene_camera(scene: bpy.types.Scene) -> bpy.types.Object:
    if scene.camera is None:
        raise AddonError("the scene has no camera: add one and make it the scene camera")
    return scene.camera


def orbit_matrices(
    camera: bpy.types.Object, pivot_distance: float, count: int, angle: float
) -> list[Matrix]:
    """World matrices of ``count`` views: ``camera`` turned about the world Z axis through the
    point ``pivot_distance`` in front of it, by angles spread evenly over ``[-angle, +angle]``
    degrees (the first view is the camera itself)."""
    m = camera.matrix_world.copy()
    forward = -(m.to_3x3() @ Vector((0.0, 0.0, 1.0))).normalized()
    pivot = m.translation + forward * pivot_distance
    if count == 1:
        angles = [0.0]
    else:
        spread = np.linspace(-angle, angle, count)
        others = sorted((a for a in spread if abs(a) > 1e-9), key=abs)
        angles = [0.0, *others][:count]
    out = []
    for a in angles:
        turn = Matrix.Translation(pivot) @ Matrix.Rotation(math.radians(a), 4, "Z")
        out.append(turn @ Matrix.Translation(-pivot) @ m)
    return out


def scene_centre(scene: bpy.types.Scene) -> Vector:
    """The centre of the bounds of the scene's visible mesh objects (world space)."""
    corners = [
        obj.matrix_world @ Vector(c)
        for obj in scene.objects
        if obj.type == "MESH" and not obj.hide_render
        for c in obj.bound_box
    ]
    if not corners:
        return Vector((0.0, 0.0, 0.0))
    lo = Vector(tuple(min(c[i] for c in corners) for i in range(3)))
    hi = Vector(tuple(max(c[i] for c in corners) for i in range(3)))
    return (lo + hi) / 2


@contextlib.contextmanager
def generated_cameras(scene: bpy.types.Scene, views: ViewSet) -> Iterator[list[bpy.types.Object]]:
    """The temporary camera objects of an orbit (copies of the scene camera's data), linked to
    the scene for the block and always removed after it."""
    cam = _scene_camera(scene)
    radius = views.orbit_radius or (scene_centre(scene) - cam.matrix_world.translation).length
    made: list[bpy.types.Object] = []
    try:
        for i, matrix in enumerate(
            orbit_matrices(cam, radius, views.orbit_count, views.orbit_angle)
        ):
            if i == 0:
                made.append(cam)
                continue
            data = cam.data.copy()
            obj = bpy.data.objects.new(f"{cam.name} orbit {i}", data)
            obj[ORBIT_MARKER] = True
            obj.matrix_world = matrix
            scene.collection.objects.link(obj)
            made.append(obj)
        yield made
    finally:
        for obj in made:
            if obj.get(ORBIT_MARKER, False):
                remove_camera(obj)


def remove_camera(obj: bpy.types.Object) -> None:
    """Removes a temporary camera object, and its camera data where nothing else uses it."""
    data = obj.data
    bpy.data.objects.remove(obj)
    if data is not None and data.users == 0:
        bpy.data.cameras.remove(data)


def pose_matrix(pose: vplace.coverage.Pose) -> Matrix:
    """The world matrix of a camera at ``pose`` (Blender's camera looks down its -Z axis)."""
    f, right, up = pose.basis()
    rot = Matrix((right, up, -f)).transposed()  # columns: the camera's x, y and z axes
    return Matrix.Translation(Vector(pose.eye.tolist())) @ rot.to_4x4()


@contextlib.contextmanager
def pose_camera(
    scene: bpy.types.Scene, pose: vplace.coverage.Pose, name: str
) -> Iterator[bpy.types.Object]:
    """A temporary camera at a coverage ``pose``: the 90-degree square view ``vplace.coverage``
    traces, linked to ``scene`` for the block and always removed after it (its data too)."""
    data = bpy.data.cameras.new(name)
    data.sensor_fit = "AUTO"
    data.angle = math.pi / 2.0
    data.clip_start, data.clip_end = vplace.coverage.NEAR, vplace.coverage.FAR
    obj = bpy.data.objects.new(name, data)
    obj[COVERAGE_MARKER] = True
    obj.matrix_world = pose_matrix(pose)
    try:
        scene.collection.objects.link(obj)
        yield obj
    finally:
        remove_camera(obj)


def resolve(
    scene: bpy.types.Scene, views: ViewSet, orbit: list[bpy.types.Object] | None = None
) -> list[ViewSpec]:
    """The views of ``views`` in ``scene``; an orbit needs its :func:`generated_cameras`."""
    views.validate()
    if views.mode == "active":
        cam = _scene_camera(scene)
        return [ViewSpec(cam.name, cam)]
    if views.mode == "cameras":
        return [ViewSpec(name, _camera(name)) for name in dict.fromkeys(views.cameras)]
    if views.mode == "frames":
        cam = _scene_camera(scene)
        frames = range(views.frame_start, views.frame_end + 1, views.frame_step)
        return [ViewSpec(f"{cam.name} frame {f}", cam, f) for f in frames]
    if orbit is None:
        raise AddonError("an orbit's cameras must be made first (views.generated_cameras)")
    return [ViewSpec(c.name, c) for c in orbit]


@contextlib.contextmanager
def specs(scene: bpy.types.Scene, views: ViewSet) -> Iterator[list[ViewSpec]]:
    """The :class:`ViewSpec` objects of ``views`` for the block (an orbit's temporary cameras
    exist for the block only)."""
    views.validate()
    if views.mode != "orbit":
        yield resolve(scene, views)
        return
    with generated_cameras(scene, views) as orbit:
        yield resolve(scene, views, orbit)


def capture_resolution(scene: bpy.types.Scene, size: int) -> tuple[int, int]:
    """The capture size: ``size`` pixels on the long side at the render's aspect ratio with its
    pixel aspect, so the capture (square pixels: ``settings.measured_frame``) frames what the
    render frames."""
    r = scene.render
    w, h = r.resolution_x * r.pixel_aspect_x, r.resolution_y * r.pixel_aspect_y
    if w <= 0 or h <= 0:
        raise AddonError("the render size is zero; set the output resolution")
    if w >= h:
        return size, max(1, round(size * h / w))
    return max(1, round(size * w / h)), size


def eye_positions(scene: bpy.types.Scene, views: Sequence[ViewSpec]) -> np.ndarray:
    """:func:`eye_views`' eyes (N x 3 float32)."""
    return eye_views(scene, views)[0]


def eye_views(scene: bpy.types.Scene, views: Sequence[ViewSpec]) -> tuple[np.ndarray, np.ndarray]:
    """Where the views' cameras stand (N x 3 float32), each at its view's frame (the scene's
    frame is put back): the eyes whose region gives the scene's working scale
    (``scene.convert.build_scene``). A camera's position, or where its view begins
    (``vplace.coverage.view_eye``: its clip start along its axis) when a surface lies between
    the two: a camera outside a wall whose clip start passes the wall stands in the room it
    sees (``vplace.coverage.camera_eye``'s rule, with Blender's ray cast). With them, where each
    camera looks (N x 3 float32, unit; zero for a panoramic camera, which looks all round):
    ``vplace.Scene``'s ``looks``."""
    original = scene.frame_current
    resolution = capture_resolution(scene, 64)
    eyes, looks = [], []
    try:
        for spec in views:
            frame = original if spec.frame is None else spec.frame
            if frame != scene.frame_current:
                scene.frame_set(frame)
            position, world_to_clip = camera_matrices(scene, spec.camera, resolution)
            near = vplace.coverage.view_eye(world_to_clip)
            origin = Vector(position.tolist())
            way = Vector(near.tolist()) - origin
            depsgraph = bpy.context.evaluated_depsgraph_get()
            hit = (
                way.length > 0.0
                and scene.ray_cast(depsgraph, origin, way.normalized(), distance=way.length)[0]
            )
            eyes.append(near if hit else position)
            pano = spec.camera.data.type == "PANO"
            axis = spec.camera.matrix_world.normalized().to_3x3() @ Vector((0.0, 0.0, -1.0))
            looks.append((0.0, 0.0, 0.0) if pano else tuple(axis.normalized()))
    finally:
        if scene.frame_current != original:
            scene.frame_set(original)
    shape = (-1, 3)
    return (
        np.asarray(eyes, dtype=np.float32).reshape(shape),
        np.asarray(looks, dtype=np.float32).reshape(shape),
    )
