"""Capture: the views, their Cycles passes (cached by the render key) and their ``vplace.View``."""
