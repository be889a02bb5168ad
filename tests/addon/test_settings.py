"""settings.py: temporary setting changes, restored in the order they were made, also when the
block raises."""

from __future__ import annotations

import bpy
import pytest

from addon.settings import SettingsGuard, at_frame, override


class Recorder:
    """An object that logs every attribute it is given, in order."""

    def __init__(self, **values: object) -> None:
        object.__setattr__(self, "log", [])
        for name, value in values.items():
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: object) -> None:
        self.log.append((name, value))
        object.__setattr__(self, name, value)


def test_override_restores_every_change_in_order_even_when_the_block_raises():
    owner = Recorder(media_type="IMAGE", file_format="PNG", color_depth="8", size=(1, 2))
    with pytest.raises(RuntimeError, match="boom"), override() as g:
        g.set(owner, "media_type", "MULTI_LAYER_IMAGE")
        g.set(owner, "file_format", "OPEN_EXR_MULTILAYER")
        g.set(owner, "file_format", "OPEN_EXR")  # changed twice: the first old value is kept
        g.set(owner, "color_depth", "32")
        g.set(owner, "size", [3, 4])
        raise RuntimeError("boom")
    assert (owner.media_type, owner.file_format, owner.color_depth) == ("IMAGE", "PNG", "8")
    assert owner.size == (1, 2)  # a sequence is saved as a copy, not a live view
    restored = owner.log[-4:]
    assert [name for name, _ in restored] == ["media_type", "file_format", "color_depth", "size"]


def test_remember_records_values_that_a_change_would_reset():
    owner = Recorder(media_type="IMAGE", file_format="PNG")
    with override() as g:
        g.remember(owner, ("media_type", "file_format"))
        object.__setattr__(owner, "file_format", "JPEG")  # as Blender resets it behind our back
        g.set(owner, "media_type", "VIDEO")
    assert (owner.media_type, owner.file_format) == ("IMAGE", "PNG")


def test_a_value_the_setting_already_has_is_not_assigned_again():
    """Blender runs a setting's update on every assignment: the render engine assigned the
    engine it already has makes Cycles drop the scene it keeps between renders. So neither the
    change nor the restore assigns a value equal to the current one (an array by its items)."""
    owner = Recorder(engine="CYCLES", samples=16, colour=(1.0, 0.5, 0.0))
    with override() as g:
        g.set(owner, "engine", "CYCLES")
        g.set(owner, "colour", [1.0, 0.5, 0.0])
        g.set(owner, "samples", 8)
        assert owner.log == [("samples", 8)]
    assert owner.log == [("samples", 8), ("samples", 16)]
    assert (owner.engine, owner.samples, owner.colour) == ("CYCLES", 16, (1.0, 0.5, 0.0))


def test_a_setting_set_to_what_it_has_is_still_restored_when_something_else_changes_it():
    """The value the block found is remembered even where the guard assigned nothing, so a
    setting that another change resets behind the guard's back comes back."""
    owner = Recorder(media_type="IMAGE", file_format="PNG")
    with override() as g:
        g.set(owner, "file_format", "PNG")
        object.__setattr__(owner, "file_format", "JPEG")  # reset by another change
    assert owner.file_format == "PNG"


def test_a_guard_restores_once():
    owner = Recorder(x=1)
    g = SettingsGuard()
    g.set(owner, "x", 2)
    g.restore()
    owner.x = 5
    g.restore()  # nothing left to restore
    assert owner.x == 5


def test_a_blender_setting_changed_twice_comes_back_as_the_user_had_it():
    """Each access to ``scene.cycles`` makes a new Python object for the same struct: the guard
    knows it for the one it changed before and keeps the user's value, not its own."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.cycles.filter_width = 1.5
    with override() as g:
        g.set(scene.cycles, "filter_width", 1.0)
        g.set(scene.cycles, "filter_width", 0.5)
    assert scene.cycles.filter_width == pytest.approx(1.5)


def test_at_frame_comes_back_when_the_block_raises():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.frame_set(3)
    with pytest.raises(ValueError), at_frame(scene, 10):
        assert scene.frame_current == 10
        raise ValueError
    assert scene.frame_current == 3
