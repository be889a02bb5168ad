"""The main job hands the scene forward: export -> capture -> fit, layout and scores -> write-back
-> files, each stage entered once (``tests/flow_trace.py`` measures it)."""

from __future__ import annotations

import pytest
from flow_trace import main_job_flow

#: Returns (entries into a file already left) of the main job, two levels deep: measured 4
#: after the restructure (38 before it, with 45 stays in 7 files: the stages called each
#: other back and forth).
MAX_RETURNS = 4


@pytest.mark.slow
def test_the_main_job_enters_each_stage_once(tmp_path):
    flow = main_job_flow(tmp_path)
    print(flow.text())
    assert flow.returns <= MAX_RETURNS, flow.text()
    stays = flow.stays
    # The stages in order, each once: the scene, the captures, the library's job, the write-back.
    firsts = [
        stays.index(name)
        for name in (
            "addon/scene/convert.py",
            "addon/capture/stage.py",
            "rust/vplace-py/python/vplace/job.py",
            "addon/writeback/stage.py",
        )
    ]
    assert firsts == sorted(firsts), flow.text()
    for stage in ("addon/scene/convert.py", "addon/capture/stage.py", "addon/writeback/stage.py"):
        assert stays.count(stage) == 1, flow.text()
