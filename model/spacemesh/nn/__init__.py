"""Torch parts of SpaceMesh: losses, networks, training. Needs the ``train`` extra."""
