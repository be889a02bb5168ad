"""The material rule (``materials.py``) as export applies it: the diffuse albedo of node trees,
base-colour textures looked up per hit through the exported UVs, alpha cut-outs that rays pass,
and the viewport colour with a warning for what the rule does not read."""

import bpy
import numpy as np
import pytest
from blender_util import empty_file, principled

from addon.compat import new_material
from addon.scene import export, materials
from addon.scene.convert import build_scene

#: A 2 x 2 texture (Blender rows bottom first): red, green / blue, white; alpha 0 on the left.
TEXELS = np.array(
    [[[1, 0, 0, 0], [0, 1, 0, 1]], [[0, 0, 1, 0], [1, 1, 1, 1]]],
    dtype=np.float32,
)


@pytest.fixture
def scene():
    empty_file()
    sc = bpy.context.scene
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    sc.collection.objects.link(cam)
    sc.camera = cam
    sun = bpy.data.objects.new("sun", bpy.data.lights.new("sun", "SUN"))
    sc.collection.objects.link(sun)
    return sc


def quad(scene, mat, z=0.0):
    """A unit quad at height ``z`` with UVs = (x, y), so UV (u, v) is the point (u, v, z)."""
    mesh = bpy.data.meshes.new("quad")
    mesh.from_pydata([(0, 0, z), (1, 0, z), (1, 1, z), (0, 1, z)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop in mesh.loops:
        co = mesh.vertices[loop.vertex_index].co
        uv.data[loop.index].uv = (co.x, co.y)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("quad", mesh)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()
    return obj


def image():
    img = bpy.data.images.new("tex", 2, 2, alpha=True, float_buffer=True)
    img.pixels.foreach_set(TEXELS.ravel())
    img.pack()
    return img


def only_material(ex, name):
    (m,) = [m for m in ex.materials if m.name == name]
    return m


def test_metal_and_glass_are_not_diffuse_bounce_sources(scene):
    metal, _ = principled("metal", **{"Base Color": (0.8, 0.4, 0.2, 1), "Metallic": 0.75})
    glass, _ = principled("glass", **{"Transmission Weight": 1.0})
    quad(scene, metal)
    quad(scene, glass, z=1.0)
    ex = export.export_scene(scene)
    # The diffuse part under the dielectric layer loses what that layer reflects (0.092).
    e = materials.dielectric_reflectance(1.5)
    np.testing.assert_allclose(
        only_material(ex, "metal").albedo, np.array([0.2, 0.1, 0.05]) * (1 - e), rtol=1e-5
    )
    np.testing.assert_allclose(only_material(ex, "glass").albedo, (0, 0, 0), atol=1e-6)


def test_image_base_colour_is_looked_up_per_hit(scene):
    mat, p = principled("textured")
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image()
    mat.node_tree.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    quad(scene, mat)
    ex = export.export_scene(scene)
    m = only_material(ex, "textured")
    assert m.texture is not None and m.textured
    assert ex.uvs is not None and ex.uvs.shape == (2, 3, 2)
    assert ex.textures[m.texture.index].shape == (2, 2, 4)
    native = build_scene(ex)
    assert native.texture_count == 1
    # Rays straight down near each texel's centre (the lookup is bilinear), off the quad's
    # diagonal: the albedo at each hit is that texel's colour.
    centres = np.array([[0.26, 0.24], [0.74, 0.26], [0.24, 0.76], [0.76, 0.74]], np.float32)
    origins = np.c_[centres, np.ones(4, np.float32)].astype(np.float32)
    down = np.tile(np.array([[0, 0, -1]], np.float32), (4, 1))
    _, tri, bary = native.intersect(origins, down)
    assert np.all(tri >= 0)
    got = native.albedo_at(tri.astype(np.uint32), bary)
    # The texel, less what the default dielectric layer over it reflects.
    want = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], np.float32)
    want *= 1 - materials.dielectric_reflectance(1.5)
    np.testing.assert_allclose(got, want, atol=0.05)


def _hits(native):
    """Rays straight down near each texel's centre: (triangles, barycentrics)."""
    centres = np.array([[0.26, 0.24], [0.74, 0.26], [0.24, 0.76], [0.76, 0.74]], np.float32)
    origins = np.c_[centres, np.ones(4, np.float32)].astype(np.float32)
    down = np.tile(np.array([[0, 0, -1]], np.float32), (4, 1))
    _, tri, bary = native.intersect(origins, down)
    assert np.all(tri >= 0)
    return tri.astype(np.uint32), bary


def test_glossy_layers_reflect_for_the_light_paths(scene):
    """A dielectric layer (IOR 1.5, level 0.5) reflects 0.092 of the light over the hemisphere
    and takes that off the diffuse albedo under it (as Cycles' Diffuse Color pass does, per
    view angle); a metal's layer reflects its base colour (Schlick's mean), textured or not.
    Before, the light paths reflected the albedo alone: a metal nothing."""
    e = materials.dielectric_reflectance(1.5, 0.5)
    assert e == pytest.approx(0.0918, abs=5e-4)
    assert materials.dielectric_reflectance(1.5, 0.0) == 0.0
    plain, _ = principled("plain", **{"Base Color": (0.5, 0.2, 0.1, 1), "Roughness": 0.7})
    matte, _ = principled("matte", **{"Specular IOR Level": 0.0})
    metal, p = principled("textured metal", Metallic=1.0)
    tex = metal.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image()
    metal.node_tree.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    quad(scene, plain)
    quad(scene, matte, z=-1.0)
    quad(scene, metal, z=-2.0)
    ex = export.export_scene(scene)
    base = np.array([0.5, 0.2, 0.1])
    np.testing.assert_allclose(only_material(ex, "plain").albedo, base * (1 - e), rtol=1e-5)
    np.testing.assert_allclose(only_material(ex, "plain").gloss, (e, e, e), rtol=1e-4)
    assert only_material(ex, "matte").gloss is None
    np.testing.assert_allclose(only_material(ex, "matte").albedo, 0.8, rtol=1e-5)
    m = only_material(ex, "textured metal")
    np.testing.assert_allclose(m.albedo, 0.0, atol=1e-6)
    assert m.texture is not None
    native = build_scene(ex)
    tri, bary = _hits(native)  # the first quad hit from above: the plain one
    np.testing.assert_allclose(native.gloss_at(tri, bary), np.full((4, 3), e), rtol=1e-4)
    # The metal quad alone: its texels at 20/21 plus 1/21.
    for o in list(scene.objects):
        if o.type == "MESH" and o.active_material is not metal:
            bpy.data.objects.remove(o)
    native = build_scene(export.export_scene(scene))
    tri, bary = _hits(native)
    want = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], np.float32) * 20 / 21 + 1 / 21
    np.testing.assert_allclose(native.albedo_at(tri, bary), 0.0, atol=1e-6)
    np.testing.assert_allclose(native.gloss_at(tri, bary), want, atol=0.05)


def test_native_gloss_is_checked():
    from addon.native import vplace

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    t = np.array([[0, 1, 2]], np.uint32)
    ids = np.zeros(1, np.uint32)
    alb = np.full((1, 3), 0.5, np.float32)
    lights = [vplace.Light.point((0.2, 0.2, 1.0), (1.0, 1.0, 1.0))]
    s = vplace.Scene(v, t, ids, alb, lights, gloss=np.full((1, 3), 0.1, np.float32))
    got = s.gloss_at(np.zeros(1, np.uint32), np.full((1, 2), 0.3, np.float32))
    np.testing.assert_allclose(got, 0.1, rtol=1e-6)
    plain = vplace.Scene(v, t, ids, alb, lights)
    assert not plain.gloss_at(np.zeros(1, np.uint32), np.full((1, 2), 0.3, np.float32)).any()
    one = np.full((1, 3), 0.1, np.float32)
    for kwargs, words in (
        ({"gloss": np.full((2, 3), 0.5, np.float32)}, "gloss"),
        ({"gloss": np.full((1, 3), np.nan, np.float32)}, "gloss"),
        ({"gloss": np.full((1, 3), -0.1, np.float32)}, "gloss"),
        ({"gloss": one, "gloss_roughness": np.full(1, 1.5, np.float32)}, "roughness"),
        ({"gloss_tint": np.ones((1, 3), np.float32)}, "need gloss"),
    ):
        with pytest.raises(vplace.InputError, match=words):
            vplace.Scene(v, t, ids, alb, lights, **kwargs)


def test_alpha_cut_surfaces_let_rays_through(scene):
    mat, p = principled("leaf")
    tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = image()
    tex.interpolation = "Closest"
    mat.node_tree.links.new(tex.outputs["Color"], p.inputs["Base Color"])
    mat.node_tree.links.new(tex.outputs["Alpha"], p.inputs["Alpha"])
    quad(scene, mat, z=1.0)
    floor_mat, _ = principled("floor")
    floor = quad(scene, floor_mat)
    floor.scale = (3, 3, 1)
    floor.location = (-1, -1, 0)
    bpy.context.view_layer.update()
    ex = export.export_scene(scene)
    leaf = only_material(ex, "leaf")
    assert leaf.alpha is not None and leaf.alpha.texture is not None
    native = build_scene(ex)
    assert native.has_alpha_tests
    # Shadow rays from under the card up through its texels: cut on the left (alpha 0).
    # Off the quad's diagonal (an edge of both triangles).
    below = np.array([[0.2, 0.3, 0.5], [0.7, 0.2, 0.5], [0.3, 0.8, 0.5], [0.8, 0.7, 0.5]])
    above = below + np.array([0, 0, 1.0])
    blocked = native.occluded(below.astype(np.float32), above.astype(np.float32))
    assert blocked.tolist() == [False, True, False, True]


def test_mix_with_transparent_is_the_cut_out(scene):
    mat = new_material("fence")
    nt = mat.node_tree
    p = nt.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (0.5, 0.5, 0.5, 1)
    transparent = nt.nodes.new("ShaderNodeBsdfTransparent")
    mix = nt.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.3  # 30 % Principled: alpha 0.3 < 0.5, cut away
    nt.links.new(transparent.outputs[0], mix.inputs[1])
    nt.links.new(p.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    quad(scene, mat)
    m = only_material(export.export_scene(scene), "fence")
    assert m.alpha is not None and m.alpha.texture is None and m.alpha.offset < m.alpha.cutoff


def test_unread_node_trees_use_the_viewport_colour_with_a_warning(scene):
    mat, p = principled("wavy")
    mat.diffuse_color = (0.1, 0.6, 0.3, 1.0)
    wave = mat.node_tree.nodes.new("ShaderNodeTexWave")
    mat.node_tree.links.new(wave.outputs["Color"], p.inputs["Base Color"])
    quad(scene, mat)
    ex = export.export_scene(scene)
    np.testing.assert_allclose(only_material(ex, "wavy").albedo, (0.1, 0.6, 0.3), rtol=1e-5)
    assert any("wavy" in w for w in ex.warnings)
