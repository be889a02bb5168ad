"""The built-in scenes: their registry and the builders of those made from code."""
