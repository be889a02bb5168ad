"""The user interface: the scene's settings, the operators, their worker thread and the panels."""
