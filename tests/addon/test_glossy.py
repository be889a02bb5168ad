"""Glossy layers (``export.ROUGH_GLOSS``): which materials have one and how rough, where a view
sees the rough ones, the reflectance and indirect light vplace models there, and the written
VPLs' specular factor, decided on what the captures see."""

import dataclasses
import math

import blender_util
import bpy
import numpy as np
import pytest
from blender_util import addon_cornell, empty_file

from addon import job as pipeline
from addon.capture import passes
from addon.capture.native_view import gloss_mask, view_of, vpl_specular, vpl_unlit
from addon.capture.passes import Capture
from addon.compat import new_material
from addon.native import vplace
from addon.scene import export
from addon.scene.convert import build_scene
from addon.writeback import apply

LUMA = np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture
def scene():
    empty_file()
    sc = bpy.context.scene
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sc.collection.objects.link(sun)
    return sc


def principled(name, **inputs):
    return blender_util.principled(name, **inputs)[0]


def shader_material(name, kind, **inputs):
    """A material whose surface is one shader node of ``kind``."""
    mat = new_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    node = nodes.new(kind)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    links.new(node.outputs[0], nodes["Material Output"].inputs["Surface"])
    return mat


def mixed(name, a, b, fac=0.5):
    """A Mix Shader of the surfaces of materials ``a`` and ``b`` (their nodes copied over)."""
    mat = new_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    nodes.remove(nodes["Principled BSDF"])
    mix = nodes.new("ShaderNodeMixShader")
    mix.inputs[0].default_value = fac
    for slot, (kind, inputs) in zip((1, 2), (a, b), strict=True):
        node = nodes.new(kind)
        for key, value in inputs.items():
            node.inputs[key].default_value = value
        links.new(node.outputs[0], mix.inputs[slot])
    links.new(mix.outputs[0], nodes["Material Output"].inputs["Surface"])
    return mat


def test_each_shader_says_whether_it_has_a_glossy_layer_and_how_rough(scene):
    cases = {
        principled("default"): 0.5,
        principled("rough", Roughness=0.9): 0.9,
        principled("no specular", **{"Specular IOR Level": 0.0}): None,
        principled("metal", Roughness=0.2, Metallic=1.0, **{"Specular IOR Level": 0.0}): 0.2,
        shader_material("diffuse", "ShaderNodeBsdfDiffuse"): None,
        shader_material("glossy", "ShaderNodeBsdfAnisotropic", Roughness=0.3): 0.3,
        shader_material("emission", "ShaderNodeEmission"): None,
        mixed(
            "diffuse + glossy",
            ("ShaderNodeBsdfDiffuse", {}),
            ("ShaderNodeBsdfAnisotropic", {"Roughness": 0.7}),
        ): 0.7,
        mixed(
            "diffuse only in the mix",
            ("ShaderNodeBsdfDiffuse", {}),
            ("ShaderNodeBsdfAnisotropic", {"Roughness": 0.1}),
            fac=0.0,
        ): None,
    }
    for mat, expected in cases.items():
        got = export.material_info(mat).gloss_roughness
        assert got == pytest.approx(expected) if expected is not None else got is None, mat.name


def quad(scene, mat, x0):
    """A unit quad at z = 0 from x = ``x0`` to ``x0 + 1``, facing +Z."""
    mesh = bpy.data.meshes.new(mat.name)
    mesh.from_pydata([(x0, 0, 0), (x0 + 1, 0, 0), (x0 + 1, 1, 0), (x0, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(mat.name, mesh)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()


def fake_capture(position, covered, camera):
    """A capture with the given G-buffer positions (H, W, 3) and coverage; other passes 0."""
    h, w = covered.shape
    rgb = np.zeros((h, w, 3), np.float32)
    depth = np.where(covered, 1.0, 1e10).astype(np.float32)
    return Capture(
        combined=rgb,
        depth=depth,
        normal=rgb,
        position=position.astype(np.float32),
        diffuse_direct=rgb,
        diffuse_indirect=np.full_like(rgb, 0.5),
        diffuse_color=np.full_like(rgb, 0.4),
        glossy_direct=rgb,
        glossy_indirect=np.full_like(rgb, 0.25),
        glossy_color=np.full_like(rgb, 0.2),
        emission=rgb,
        environment=rgb,
        samples=1,
        render_seconds=0.0,
        key="k",
        view="v",
        camera="v",
        camera_position=np.asarray(camera, np.float32),
        world_to_clip=np.eye(4, dtype=np.float32),
    )


def test_the_mask_finds_the_rough_surface_each_pixel_sees(scene):
    quad(scene, principled("rough", Roughness=0.8), 0.0)
    quad(scene, principled("sharp", Roughness=0.1), 1.0)
    quad(scene, shader_material("matte", "ShaderNodeBsdfDiffuse"), 2.0)
    exported = export.export_scene(scene)
    assert exported.rough_gloss.sum() == 1 and exported.sharp_gloss.sum() == 1
    native = build_scene(exported)
    # One row of pixels over the three quads' centres and one pixel that sees nothing.
    position = np.array([[[0.5, 0.5, 0.0], [1.5, 0.5, 0.0], [2.5, 0.5, 0.0], [0.0, 0.0, 0.0]]])
    covered = np.array([[True, True, True, False]])
    mask = gloss_mask(native, exported, fake_capture(position, covered, (1.5, 0.5, 3.0)))
    assert mask is not None
    np.testing.assert_array_equal(mask, [[1.0, 0.0, 1.0, 0.0]])


def test_without_sharp_layers_every_covered_pixel_counts_and_without_rough_none(scene):
    quad(scene, principled("rough", Roughness=0.8), 0.0)
    exported = export.export_scene(scene)
    native = build_scene(exported)
    position = np.zeros((1, 2, 3))
    covered = np.array([[True, False]])
    cap = fake_capture(position, covered, (0.5, 0.5, 3.0))
    np.testing.assert_array_equal(gloss_mask(native, exported, cap), [[1.0, 0.0]])
    scene.objects["rough"].data.materials[0] = shader_material("matte", "ShaderNodeBsdfDiffuse")
    exported = export.export_scene(scene)
    assert gloss_mask(build_scene(exported), exported, cap) is None


def test_the_modelled_reflectance_and_indirect_light_add_the_glossy_layer_where_masked():
    covered = np.array([[True, True]])
    cap = fake_capture(np.zeros((1, 2, 3)), covered, (0.0, 0.0, 1.0))
    gloss = np.array([[1.0, 0.0]], np.float32)
    np.testing.assert_allclose(cap.reflectance(gloss)[0, :, 0], [0.6, 0.4])
    np.testing.assert_allclose(cap.modelled_indirect(gloss)[0, :, 0], [0.25, 0.2])
    np.testing.assert_allclose(cap.reflectance(None), cap.albedo)
    np.testing.assert_allclose(cap.modelled_indirect(None), cap.indirect)


def test_a_surface_without_a_diffuse_layer_sends_on_the_light_something_else_measures():
    """The pixel emitters' irradiance: the diffuse passes wherever the diffuse layer holds at
    least ``DIFFUSE_SHARE`` of the reflectance (they measure it the same from every view); on a
    rough metal, whose diffuse passes Cycles leaves black however lit it is, vplace's own direct
    light where given (else the glossy direct pass) and the glossy indirect pass, in proportion
    between."""
    covered = np.ones((1, 5), bool)
    cap = fake_capture(np.zeros((1, 5, 3)), covered, (0.0, 0.0, 1.0))

    def rgb(*values):
        return np.repeat(np.array(values, np.float32)[None, :, None], 3, axis=-1)

    # A rough metal, a matte surface, both layers, a weak diffuse layer (a share of 1/21), and a
    # pixel without either colour.
    cap = dataclasses.replace(
        cap,
        diffuse_color=rgb(0.0, 0.4, 0.4, 0.01, 0.0),
        glossy_color=rgb(0.2, 0.0, 0.2, 0.2, 0.0),
        diffuse_direct=rgb(0.0, 1.0, 1.0, 1.0, 0.7),
        glossy_direct=rgb(2.0, 0.0, 4.0, 3.0, 0.0),
        diffuse_indirect=rgb(0.0, 0.5, 0.5, 0.5, 0.1),
        glossy_indirect=rgb(0.3, 0.0, 0.8, 0.8, 0.0),
    )
    assert passes.DIFFUSE_SHARE == 0.1
    t = (0.01 / 0.21) / 0.1
    gloss = np.ones((1, 5), np.float32)
    direct, indirect = cap.reflected_irradiance(gloss)
    np.testing.assert_allclose(direct[0, :, 0], [2.0, 1.0, 1.0, t + 3 * (1 - t), 0.7], rtol=1e-5)
    np.testing.assert_allclose(
        indirect[0, :, 0], [0.3, 0.5, 0.5, 0.5 * t + 0.8 * (1 - t), 0.1], rtol=1e-5
    )
    np.testing.assert_allclose(cap.glossy_stand_in(gloss)[0], [1.0, 0.0, 0.0, 1 - t, 0.0])
    # vplace's own direct light stands in instead of GlossDir where given.
    own = rgb(5.0, 6.0, 7.0, 8.0, 9.0)
    direct, indirect_again = cap.reflected_irradiance(gloss, own)
    np.testing.assert_allclose(direct[0, :, 0], [5.0, 1.0, 1.0, t + 8 * (1 - t), 0.7], rtol=1e-5)
    np.testing.assert_allclose(indirect_again, indirect)
    # Where the glossy layer is left to EEVEE, and without a mask, the diffuse passes alone.
    direct, _ = cap.reflected_irradiance(np.array([[0.0, 1.0, 0.0, 0.0, 1.0]], np.float32))
    np.testing.assert_allclose(direct[0, :, 0], [0.0, 1.0, 1.0, 1.0, 0.7], rtol=1e-6)
    direct, indirect = cap.reflected_irradiance(None)
    assert direct is cap.diffuse_direct and indirect is cap.diffuse_indirect
    assert not cap.glossy_stand_in(None).any()


def test_a_sunlit_rough_metal_floor_lights_the_wall_beside_it(scene):
    """Sponza's curtains are a rough metal (metallic 1): Cycles writes no diffuse pass on them,
    and the layout's pixel emitters read the diffuse passes, so the sunniest surface a view saw
    sent nothing on (vplace's light paths, which leave a VPL only where a surface is diffuse,
    send nothing off a metal either). A sunlit rough-metal floor beside a white wall, both in
    view: the layout's VPLs light the wall with about the indirect light Cycles renders there."""
    sun = scene.objects["sun"]
    sun.data.energy = 5.0
    sun.rotation_euler = (math.radians(40.0), 0.0, math.radians(90.0))
    metal = principled("metal", Roughness=1.0, Metallic=1.0, **{"Base Color": (0.5, 0.5, 0.5, 1)})
    white = principled(
        "white", Roughness=1.0, **{"Base Color": (0.8, 0.8, 0.8, 1), "Specular IOR Level": 0.0}
    )
    for name, verts, mat in (
        ("floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], metal),
        ("wall", [(-2, 2, 0), (2, 2, 0), (2, 2, 3), (-2, 2, 3)], white),
    ):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
        mesh.materials.append(mat)
        scene.collection.objects.link(bpy.data.objects.new(name, mesh))
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.location = (0.0, -1.9, 1.6)
    cam.rotation_euler = (math.radians(60.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    bpy.context.view_layer.update()
    cap = passes.capture(scene, resolution=(32, 24), samples=32, seed=0)
    floor = cap.covered & (cap.position[..., 2] < 0.01)
    wall = cap.covered & (cap.position[..., 1] > 1.99)
    assert floor.sum() > 100 and wall.sum() > 100
    assert float(cap.diffuse_direct[floor].max()) < 1e-3  # no diffuse pass on the metal
    exported = export.export_scene(scene)
    native = build_scene(exported)
    mask = gloss_mask(native, exported, cap)
    assert mask is not None
    view = view_of(cap, gloss=mask, scene=native)
    params = vplace.LayoutParams(budget=256, alpha=0.0, cell_px=8, iterate=False, seed=0)
    laid = vplace.layout(native, [view], params)
    light, _ = vplace.evaluate(native, view, laid.vpls)
    got = float((light @ LUMA)[wall].mean())
    cycles = float((cap.indirect @ LUMA)[wall].mean())
    assert got == pytest.approx(cycles, rel=0.4)


def decide(native, exported, captures):
    """``vpl_specular`` on ``captures`` and their glossy masks, as the capture stage calls it."""
    return vpl_specular(
        native, exported, captures, [gloss_mask(native, exported, c) for c in captures]
    )


def test_the_vpls_specular_follows_the_glossy_light_the_captures_see(scene):
    """1 where the rough layers show the captures at least as much glossy indirect light as the
    sharp ones (EEVEE then shows the VPLs' broad glossy bounce the evaluator counts), else 0 (a
    VPL's disk would show in the sharp layers as a spot): summed over every capture's pixels,
    each weighted by its Glossy Indirect x Glossy Color."""
    quad(scene, principled("rough", Roughness=0.8), 0.0)
    quad(scene, principled("sharp", Roughness=0.1), 1.0)
    exported = export.export_scene(scene)
    native = build_scene(exported)

    def cap(*xs, light=None):
        position = np.array([[[x, 0.5, 0.0] for x in xs]])
        c = fake_capture(position, np.ones((1, len(xs)), bool), (1.0, 0.5, 3.0))
        if light is not None:
            glossy = np.repeat(np.array(light, np.float32)[None, :, None], 3, axis=-1)
            c = dataclasses.replace(c, glossy_indirect=glossy)
        return c

    assert decide(native, exported, [cap(0.5, 0.5, 1.5)]) == 1.0
    assert decide(native, exported, [cap(0.5, 1.5)]) == 1.0  # a tie keeps it
    assert decide(native, exported, [cap(0.5, 1.5, 1.5)]) == 0.0
    assert decide(native, exported, [cap(0.5, 0.5), cap(1.5, 1.5, 1.5)]) == 0.0
    assert decide(native, exported, [cap(0.5, 1.5, 1.5, light=[1.0, 0.25, 0.25])]) == 1.0
    # Without a sharp layer it is on whatever the views see; without a rough one, off.
    scene.objects["sharp"].data.materials[0] = shader_material("matte", "ShaderNodeBsdfDiffuse")
    exported = export.export_scene(scene)
    assert decide(build_scene(exported), exported, [cap(1.5, 1.5)]) == 1.0
    scene.objects["rough"].data.materials[0] = principled("sharp 2", Roughness=0.2)
    exported = export.export_scene(scene)
    assert decide(build_scene(exported), exported, [cap(0.5)]) == 0.0


@pytest.mark.parametrize("specular", [0.0, 1.0])
def test_the_written_vpls_take_the_specular_factor(scene, specular):
    vpls = vplace.VplSet(
        np.array([[0.0, 0.0, 1.0]], np.float32),
        np.array([[0.0, 0.0, 1.0]], np.float32),
        np.ones((1, 3), np.float32),
    )
    coll = apply.write_vpls(scene, vpls, scene_diagonal=3.0, specular=specular)
    assert [o.data.specular_factor for o in coll.objects] == [specular]


def faces(scene, name, mats, x0):
    """One object of unit quads side by side from x = ``x0``, quad i of material ``mats[i]``."""
    mesh = bpy.data.meshes.new(name)
    verts = [(x0 + i + dx, dy, 0) for i in range(len(mats)) for dx, dy in _CORNERS]
    mesh.from_pydata(verts, [], [tuple(range(4 * i, 4 * i + 4)) for i in range(len(mats))])
    for mat in dict.fromkeys(mats):
        mesh.materials.append(mat)
    slots = list(dict.fromkeys(mats))
    mesh.polygons.foreach_set("material_index", [slots.index(m) for m in mats])
    obj = bpy.data.objects.new(name, mesh)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


_CORNERS = ((0, 0), (1, 0), (1, 1), (0, 1))


def test_the_vpls_leave_unlit_the_objects_whose_every_material_is_sharp_and_not_diffuse(scene):
    """Sharp metal and glass get no VPL light the evaluator counts (their Diffuse Color is
    black), only EEVEE's mirrored VPL disks; a sharp layer over a diffuse base, a rough metal
    and an object with a diffuse face stay lit, and with the specular off nothing is left out
    (the VPLs give such a surface nothing)."""
    metal = principled("metal", Metallic=1.0, Roughness=0.3)
    matte = principled("matte", Roughness=0.9)
    faces(scene, "rough", [principled("rough", Roughness=0.8)], 0.0)
    faces(scene, "cube", [metal, metal], 1.0)
    faces(
        scene, "pane", [principled("glass", **{"Transmission Weight": 1.0, "Roughness": 0.0})], 3.0
    )
    faces(scene, "varnished", [principled("varnish", Roughness=0.1)], 4.0)
    faces(scene, "brushed", [principled("rough metal", Metallic=1.0, Roughness=0.7)], 5.0)
    faces(
        scene,
        "mirror",
        [shader_material("mirror", "ShaderNodeBsdfAnisotropic", Roughness=0.05)],
        6.0,
    )
    faces(scene, "trimmed", [metal, matte], 7.0)
    exported = export.export_scene(scene)
    shown = {exported.materials[m].name for m in exported.object_materials["trimmed"]}
    assert shown == {"metal", "matte"}
    assert vpl_unlit(exported, 1.0) == ["cube", "mirror", "pane"]
    assert vpl_unlit(exported, 0.0) == []


def test_a_lamps_mirror_image_counts_as_seen_light_and_a_lit_surface_does_not():
    """``Capture.seen_light``: Emit + Env, plus the glossy direct light of pixels above
    ``MIRRORED_LAMP`` times the view's mean direct light (a lamp seen in chrome)."""
    from addon.capture.passes import MIRRORED_LAMP

    n = 100
    covered = np.ones((1, n), bool)
    covered[0, -1] = False
    glossy = np.full((1, n, 3), 0.5, np.float32)  # x GlossCol 0.2: a surface at 0.1
    glossy[0, 1], glossy[0, 2], glossy[0, -1] = 4.0, 400.0, 900.0
    emission = np.zeros_like(glossy)
    emission[0, 3] = 7.0
    cap = fake_capture(np.zeros((1, n, 3)), covered, (0.0, 0.0, 1.0))
    cap = dataclasses.replace(cap, glossy_direct=glossy, emission=emission)
    lum = np.asarray(vplace.LUMINANCE)
    mean = float((cap.direct @ lum)[covered].mean())
    assert 0.8 < MIRRORED_LAMP * mean < 80.0  # pixel 1 a lit surface, pixel 2 a lamp's image
    seen = cap.seen_light @ lum
    np.testing.assert_allclose(seen[0, :5], [0.0, 0.0, 80.0, 7.0, 0.0], rtol=1e-5)
    assert seen[0, 5:].max() == 0.0  # nor the uncovered pixel, however bright
    found = vplace.job.seen_directly(cap.seen_light, cap.direct)
    assert np.flatnonzero(found).tolist() == [2, 3]


def test_a_sharp_glossy_floor_still_counts_the_light_its_diffuse_layer_receives():
    """The layout's pixel flux factor (``Layout.pixel_flux_scale``) compares the direct light
    the captured surfaces receive, by their pixels (``DiffDir``) and by the light paths' hits,
    on surfaces with a diffuse layer. The Cornell box's floor given a lacquer (a Mix of 0.4
    white diffuse and 0.6 Glossy at roughness 0.2: its Glossy Color above its Diffuse Color,
    a sharp layer the reflectance leaves to EEVEE) still has one. Read as the reflectance less
    the Glossy Color it had none: its pixels dropped out, its hits did not, and the factor rose
    from 1.06 to 1.21 (my gallery's sunlit oak floor: 11.5, every pixel VPL that much too
    bright before the refit)."""
    with addon_cornell(cell_px=8, capture_size=48, samples=8, vpl_budget=64) as sc:
        scales = []
        for finish in (False, True):
            if finish:
                lacquer = mixed(
                    "lacquer",
                    ("ShaderNodeBsdfDiffuse", {"Color": (0.6, 0.6, 0.6, 1.0)}),
                    ("ShaderNodeBsdfGlossy", {"Roughness": 0.2}),
                    fac=0.6,
                )
                sc.objects["floor"].data.materials[0] = lacquer
            job = pipeline.Job.from_settings(sc.vplace)
            job.method = "vplace"
            prep = pipeline.prepare(sc, job, pipeline.quiet_timer())
            cap = prep.captures[0]
            if finish:
                floor = cap.covered & (cap.position[..., 2] < 1e-3)
                glossy, diffuse = cap.glossy_color[floor] @ LUMA, cap.diffuse_color[floor] @ LUMA
                assert np.median(glossy) > np.median(diffuse)
                mask = gloss_mask(prep.scene, prep.exported, cap)
                assert floor.sum() > 100 and (mask is None or not mask[floor].any())
            scales.append(pipeline.lay_out(prep, job).layout.pixel_flux_scale)
        assert scales[1] == pytest.approx(scales[0], abs=0.05)
