"""The benchmark scripts run (tiny sizes): a bench that no longer runs is a measurement lost;
and the pixel budget that bounds the layout's and the refit's cost over many views."""

import pytest
import vplace
import vplace.bench_layout


def test_bench_layout_runs_for_several_views(capsys):
    vplace.bench_layout.main(
        ["--width", "48", "--height", "32", "--budget", "16", "--views", "2", "--repeat", "1"]
    )
    out = capsys.readouterr().out
    assert "2 view(s) of 48x32, 16 VPLs" in out
    assert "layout + refit of its powers" in out and "peak memory" in out
    assert "BVH / brute force" in out
    assert "full-resolution RMSE of layout + refit, every view: stride 4:" in out


def test_the_pixel_budget_keeps_stride_4_for_one_view_and_bounds_many():
    class V:
        def __init__(self, w, h):
            self.width, self.height = w, h

    assert vplace.stride_for([V(640, 360)]) == 4  # 14,400 strided pixels: the budget
    assert vplace.stride_for([V(320, 180)] * 3) == 4  # the report's Sponza fit views
    assert vplace.stride_for([V(16, 16)]) == vplace.budget.MIN_STRIDE  # never finer than 4
    many = [V(640, 360)] * 4
    stride = vplace.stride_for(many)
    assert stride == 8
    strided = sum(-(-v.width // stride) * -(-v.height // stride) for v in many)
    assert strided <= vplace.PIXEL_BUDGET
    with pytest.raises(ValueError, match="pixel budget"):
        vplace.stride_for(many, budget=0)
    with pytest.raises(ValueError, match="finest stride"):
        vplace.stride_for(many, min_stride=0)


def test_the_refit_samples_the_captures_on_a_budget_of_its_own():
    class V:
        def __init__(self, w, h):
            self.width, self.height = w, h

    # The report's three 192x108 captures: stride 2 (15,552 pixels), where the iteration's 4
    # left the refit 3,888 for 256 powers.
    assert vplace.refit_stride_for([V(192, 108)] * 3) == 2
    assert vplace.refit_stride_for([V(16, 16)]) == vplace.budget.REFIT_MIN_STRIDE == 2
    big = [V(640, 360)] * 3
    stride = vplace.refit_stride_for(big)
    assert stride == 4
    strided = sum(-(-v.width // stride) * -(-v.height // stride) for v in big)
    assert strided <= vplace.REFIT_PIXEL_BUDGET
