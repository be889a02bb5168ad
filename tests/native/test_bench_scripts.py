"""The benchmark scripts run (tiny sizes): a bench that no longer runs is a measurement lost."""

import vplace.bench_layout


def test_bench_layout_runs_for_several_views(capsys):
    vplace.bench_layout.main(
        ["--width", "48", "--height", "32", "--budget", "16", "--views", "2", "--repeat", "1"]
    )
    out = capsys.readouterr().out
    assert "2 view(s) of 48x32, 16 VPLs" in out
    assert "layout + refit of its powers" in out and "peak memory" in out
    assert "BVH / brute force" in out
