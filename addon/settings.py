"""Temporary changes to Blender settings, always restored.

``override()`` records each attribute it changes and restores them all on exit, also when the
body raises. Restoring runs in the order the changes were made, so dependent settings (an
image's ``media_type`` before its ``file_format`` before its ``color_depth``) come back right.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any


def _plain(value: Any) -> Any:
    """``value`` as it is remembered: a Blender array (a colour, a vector) as a tuple."""
    if hasattr(value, "__len__") and not isinstance(value, str):
        return tuple(value)
    return value


def _same(a: Any, b: Any) -> bool:
    """Whether setting ``b`` where ``a`` is would change nothing (arrays by their items)."""
    try:
        return bool(_plain(a) == _plain(b))
    except (TypeError, ValueError):  # pragma: no cover - values that do not compare
        return False


class SettingsGuard:
    """Records attribute changes on Blender structs and undoes them."""

    def __init__(self) -> None:
        self._saved: list[tuple[Any, str, Any]] = []

    def set(self, owner: Any, attr: str, value: Any) -> None:
        """Sets ``owner.attr = value``, remembering the old value the first time. A value equal
        to the current one is not set again: Blender runs a setting's update on every
        assignment, and assigning the render engine it already has makes Cycles drop the scene
        it keeps between renders (``render.use_persistent_data``) and build it again."""
        old = getattr(owner, attr)
        # ``==``, not ``is``: each access to a Blender struct (``scene.cycles``) makes a new
        # Python object for it; equal ones are the same struct.
        if not any(a == attr and o == owner for o, a, _ in self._saved):
            self._saved.append((owner, attr, _plain(old)))
        if not _same(old, value):
            setattr(owner, attr, value)

    def remember(self, owner: Any, attrs: tuple[str, ...]) -> None:
        """Records the current values of ``attrs`` without changing them, in this order.

        Use it before changing a setting that silently changes others (an image's
        ``media_type`` resets its ``file_format`` and ``color_depth``).
        """
        for attr in attrs:
            if hasattr(owner, attr):  # a setting of a later Blender (``media_type``: 5.0)
                self.set(owner, attr, getattr(owner, attr))

    def image_format(self, settings: Any, file_format: str, multilayer: bool = False) -> None:
        """Sets an image's ``file_format`` (``"PNG"``, ``"OPEN_EXR"``), a multilayer EXR when
        ``multilayer``: from Blender 5.0 through ``media_type``, before it as the format
        ``OPEN_EXR_MULTILAYER``."""
        if hasattr(settings, "media_type"):
            self.set(settings, "media_type", "MULTI_LAYER_IMAGE" if multilayer else "IMAGE")
            if not multilayer:
                self.set(settings, "file_format", file_format)
        else:
            self.set(
                settings, "file_format", f"{file_format}_MULTILAYER" if multilayer else file_format
            )

    def restore(self) -> None:
        """Puts every recorded attribute back, in the order they were first changed."""
        errors = []
        for owner, attr, old in self._saved:
            try:
                if not _same(getattr(owner, attr), old):
                    setattr(owner, attr, old)
            except (AttributeError, TypeError, ValueError) as exc:  # pragma: no cover
                errors.append(f"{attr}: {exc}")
        self._saved.clear()
        if errors:  # pragma: no cover
            raise RuntimeError("could not restore settings: " + "; ".join(errors))


def standard_view(g: SettingsGuard, scene: Any) -> None:
    """The colour management a measured render needs: the Standard view transform, no look,
    exposure 0, gamma 1 (the saved float pixels are then scene-linear)."""
    vs = scene.view_settings
    g.set(vs, "view_transform", "Standard")
    g.set(vs, "look", "None")
    g.set(vs, "exposure", 0.0)
    g.set(vs, "gamma", 1.0)


def measured_frame(g: SettingsGuard, scene: Any, camera: Any | None = None) -> None:
    """What a measured render (a capture, a truth, a scored EEVEE frame) sets so that its pixels
    line up with the captures' G-buffer: square pixels (the size keeps the render's shape with
    its pixel aspect, ``capture.views.capture_resolution``; Blender cannot write a multilayer
    EXR of non-square pixels), one view (no stereo pair), no motion blur and, for ``camera``,
    no depth of field: a G-buffer of blurred positions and normals belongs to no surface (a
    camera moving 1 m a frame with the render's motion blur on: 54 % of the studio capture's
    normals shorter than 0.9, against 6 % at the edges without; stop 80)."""
    r = scene.render
    g.set(r, "pixel_aspect_x", 1.0)
    g.set(r, "pixel_aspect_y", 1.0)
    g.set(r, "use_multiview", False)
    g.set(r, "use_motion_blur", False)
    if camera is not None:
        sharp(g, camera)


def sharp(g: SettingsGuard, camera: Any) -> None:
    """``camera`` without depth of field (:func:`measured_frame`)."""
    if camera.type == "CAMERA":
        g.set(camera.data.dof, "use_dof", False)


@contextlib.contextmanager
def at_frame(scene: Any, frame: int | None) -> Iterator[None]:
    """The scene at ``frame`` for the block (``None``: as it is); the frame it was at comes back
    after, also when the block raises."""
    if frame is None or frame == scene.frame_current:
        yield
        return
    old = scene.frame_current
    scene.frame_set(frame)
    try:
        yield
    finally:
        scene.frame_set(old)


@contextlib.contextmanager
def override() -> Iterator[SettingsGuard]:
    """A ``SettingsGuard`` whose changes are undone when the block ends, however it ends."""
    guard = SettingsGuard()
    try:
        yield guard
    finally:
        guard.restore()
