"""Small meshes made in code: tests never read ../shared/meshes."""

from spacemesh.examples import cube_quads, icosphere, prism, torus_grid

__all__ = ["cube_quads", "icosphere", "prism", "torus_grid"]
