"""The mesh between the passes of an automatic repair, how it maps to the working mesh,
and which region made each of its faces and vertices (:class:`Passes`): what the fills
of :mod:`spacemesh.repair.fill` replace a region's patch in.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.typed import BoolArray, IntArray


@dataclass
class Passes:
    """The mesh between passes, how it maps to the working mesh, and what the passes did.

    ``passes`` holds each model pass's :class:`spacemesh.repair.api.RepairStats` (the
    pass's mesh is the state's once applied, so it is not kept: on a mesh of 300,000
    faces each kept pass held 20 MB).
    """

    mesh: PolygonMesh
    vertex_map: IntArray  # working vertex -> current vertex (-1 removed)
    face_source: IntArray  # current face -> working face (-1 new)
    wedge: IntArray  # current face -> fallback wedge (-1 none)
    origin: IntArray  # current vertex -> region that made it (-1: none)
    made_by: IntArray  # current face -> region that made it (-1: an input face)
    passes: list[Any] = field(default_factory=list)

    @classmethod
    def of(cls, mesh: PolygonMesh) -> Passes:
        """The state before any pass: ``mesh`` as it is, nothing made by a region."""
        return cls(mesh, np.arange(mesh.n_vertices), np.arange(mesh.n_faces),
                   np.full(mesh.n_faces, -1, dtype=np.int64),
                   np.full(mesh.n_vertices, -1, dtype=np.int64),
                   np.full(mesh.n_faces, -1, dtype=np.int64))

    def apply(self, vertex_map: IntArray, face_source: IntArray, mesh: PolygonMesh,
              region: int = -1) -> None:
        """Follow one more pass (its vertex map and face sources over the current mesh);
        the vertices it makes are ``region``'s (-1: none)."""
        self.vertex_map = np.where(self.vertex_map >= 0,
                                   vertex_map[np.maximum(self.vertex_map, 0)], -1)
        old = np.maximum(face_source, 0)
        self.face_source = np.where(face_source >= 0, self.face_source[old], -1)
        self.wedge = np.where(face_source >= 0, self.wedge[old], -1)
        self.made_by = np.where(face_source >= 0, self.made_by[old], region)
        origin = np.full(mesh.n_vertices, region, dtype=np.int64)
        alive = vertex_map >= 0
        origin[vertex_map[alive]] = self.origin[alive]
        self.origin = origin
        self.mesh = mesh

    def vertices_of(self, working: BoolArray) -> BoolArray:
        """(V_current,) the current vertices that are the working vertices ``working``."""
        marked = np.zeros(self.mesh.n_vertices, dtype=bool)
        marked[self.vertex_map[working & (self.vertex_map >= 0)]] = True
        return marked

    def faces_of(self, working: BoolArray) -> BoolArray:
        """(F_current,) the current faces that are the working mesh's faces ``working``."""
        return (self.face_source >= 0) & working[np.maximum(self.face_source, 0)]
