"""The one module of the add-on that imports the ``vplace`` package, and nothing of the add-on.

When the add-on is installed as an extension, Blender installs the bundled ``vplace`` wheel
(``wheels/`` in the manifest); in development the package comes from the virtual environment.
Every other module reaches the native library through this one.
"""

from __future__ import annotations

import vplace
import vplace.images
import vplace.job
import vplace.markdown
import vplace.par2d_measure
import vplace.temporal

__all__ = ["vplace"]
