"""How densely the layout iteration and the power refit sample the views' pixels.

Both trace a shadow ray per (strided pixel, VPL) pair, so their cost grows with the pixels of
every view laid out for. They sample every ``stride``-th pixel in x and y, with the stride
chosen so that all views together give about :data:`PIXEL_BUDGET` pixels, never finer than
:data:`MIN_STRIDE`: one 640x360 view, or three of the report's Sponza views, keep stride 4; four
640x360 views take stride 8 and cost what one does. The regression still uses every pixel.
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


class _Sized(Protocol):
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...


def stride_for(views: Sequence[_Sized], budget: int = PIXEL_BUDGET) -> int:
    """The stride at which ``views`` give at most about ``budget`` strided pixels together."""
    if budget < 1:
        raise ValueError(f"the pixel budget must be positive, got {budget}")
    total = sum(v.width * v.height for v in views)
    return max(MIN_STRIDE, math.ceil(math.sqrt(total / budget)))
