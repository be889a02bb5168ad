"""The export benchmark runs (tiny) and measures what it says: a textured terrain's triangles,
its one texture, positive times and memory."""

from addon.scene import bench_export


def test_the_export_benchmark_measures_a_textured_terrain():
    lines: list[str] = []
    out = bench_export.run(grid=21, texture=16, repeat=1, log=lines.append)
    assert out["triangles"] == 2 * 20 * 20
    assert (out["textures"], out["texels"]) == (1, 16 * 16)
    assert out["export_seconds"] > 0 and out["build_seconds"] > 0
    assert 0 < out["export_peak_bytes"] < out["process_peak_bytes"]
    assert "export_scene" in lines[2] and "process peak" in lines[-1]
