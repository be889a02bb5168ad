"""Scene export: the Blender scene (meshes, materials, lights, world) as arrays and as a
``vplace.Scene``."""
