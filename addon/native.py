"""The one module of the add-on that imports the ``vplace`` package.

When the add-on is installed as an extension, Blender installs the bundled ``vplace`` wheel
(``wheels/`` in the manifest); in development the package comes from the virtual environment.
Every other module reaches the native library through ``from .native import vplace``.
"""

import vplace

__all__ = ["vplace"]
