"""How densely the layout iteration and the power refit sample the views' pixels.

Both trace a shadow ray per (strided pixel, VPL) pair, so their cost grows with the pixels of
every view laid out for. They sample every ``stride``-th pixel in x and y, with the stride
chosen so that all views together give about :data:`PIXEL_BUDGET` pixels, never finer than
:data:`MIN_STRIDE`: one 640x360 view, or three of the report's Sponza views, keep stride 4; four
640x360 views take stride 8 and cost what one does. The regression still uses every pixel.

The power refit samples the captured views alone, on a budget of its own
(:data:`REFIT_PIXEL_BUDGET`, :func:`refit_stride_for`): it solves for one power per VPL, and at
the report's 192x108 the iteration's stride 4 left it 1,296 pixels a view for 256 unknowns.
At stride 2 instead (one scale per VPL, no other change) the refit scored .004-.007 higher SSIM
on every view of the sky room and .002-.008 on Sponza's fit views, though .014 lower on
Sponza's held-out Alcove (8 seeds; ARCHITECTURE.md, "The refit's power groups"); it costs
0.25-0.4 s there against 0.1 s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

#: Strided pixels the iteration and the refit trace over all views together (one 640x360
#: view at stride 4).
PIXEL_BUDGET = 14_400
#: The finest stride: every 4th pixel in x and y.
MIN_STRIDE = 4
#: Strided pixels the power refit traces over the captured views together (one 640x360 view at
#: stride 2, three at stride 4).
REFIT_PIXEL_BUDGET = 4 * PIXEL_BUDGET
#: The refit's finest stride: every 2nd pixel in x and y (every pixel measured .0004-.003 SSIM
#: more on the sky room and Sponza at three times the cost).
REFIT_MIN_STRIDE = 2


class _Sized(Protocol):
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...


def stride_for(
    views: Sequence[_Sized], budget: int = PIXEL_BUDGET, min_stride: int = MIN_STRIDE
) -> int:
    """The stride at which ``views`` give at most about ``budget`` strided pixels together,
    never finer than ``min_stride``."""
    if budget < 1:
        raise ValueError(f"the pixel budget must be positive, got {budget}")
    if min_stride < 1:
        raise ValueError(f"the finest stride must be at least 1, got {min_stride}")
    total = sum(v.width * v.height for v in views)
    return max(min_stride, math.ceil(math.sqrt(total / budget)))


def refit_stride_for(captures: Sequence[_Sized]) -> int:
    """The power refit's stride over the captured views ``captures``: :data:`REFIT_PIXEL_BUDGET`,
    never finer than :data:`REFIT_MIN_STRIDE`."""
    return stride_for(captures, REFIT_PIXEL_BUDGET, REFIT_MIN_STRIDE)
