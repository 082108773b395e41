"""Mesh primitives: the ground floor that every other package builds on.

* :mod:`~spacemesh.primitives.keys`: integer keys of undirected edges;
* :mod:`~spacemesh.primitives.graph`: connected components of node pairs, the uniform
  (umbrella) adjacency;
* :mod:`~spacemesh.primitives.triangles`: polygons and polygon meshes as triangles,
  signed volume (also per corner), surface area;
* :mod:`~spacemesh.primitives.closest`: closest points on triangles, nearest triangles;
* :mod:`~spacemesh.primitives.masks`: faces touching vertices, vertices of faces, a
  mesh restricted to some faces, some faces flipped;
* :mod:`~spacemesh.primitives.sampling`: points sampled on a surface;
* :mod:`~spacemesh.primitives.frame`: the unit frame of a mesh;
* :mod:`~spacemesh.primitives.decimation`: quadric-error decimation;
* :mod:`~spacemesh.primitives.welding`: exactly equal positions merged.

They read and make :class:`~spacemesh.mesh.PolygonMesh` and import nothing else of
ours, so any layer may use them.
"""

from spacemesh.primitives.decimation import decimate
from spacemesh.primitives.frame import normalize
from spacemesh.primitives.graph import component_labels, uniform_adjacency
from spacemesh.primitives.keys import edge_keys, unique_edges
from spacemesh.primitives.masks import faces_subset, faces_touching, flip_faces, vertices_of
from spacemesh.primitives.sampling import sample_surface
from spacemesh.primitives.triangles import (
    fan_volumes,
    newell_normal,
    signed_volume,
    surface_area,
    triangle_areas,
    triangles_of,
    triangulate_faces,
    triangulate_manifold,
    triangulate_polygon,
)
from spacemesh.primitives.vectors import (
    bounding_spheres,
    cross_rows,
    triangle_normals,
    unit_rows,
)
from spacemesh.primitives.welding import weld

__all__ = [
    "bounding_spheres",
    "component_labels",
    "cross_rows",
    "decimate",
    "edge_keys",
    "faces_subset",
    "faces_touching",
    "fan_volumes",
    "flip_faces",
    "newell_normal",
    "normalize",
    "sample_surface",
    "signed_volume",
    "surface_area",
    "triangle_areas",
    "triangle_normals",
    "triangles_of",
    "triangulate_faces",
    "triangulate_manifold",
    "triangulate_polygon",
    "uniform_adjacency",
    "unique_edges",
    "unit_rows",
    "vertices_of",
    "weld",
]
