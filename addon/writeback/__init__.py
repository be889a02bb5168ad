"""Write-back: the VPLs as Blender lights, the stand-in lights, EEVEE's set-up and renders, the
PAR 2D bake."""
