"""An offscreen gallery: input points, our mesh, PSR* and the ground truth, side by side.

Rendered with matplotlib's 3-D axes and ``Poly3DCollection`` on the Agg backend, so it
needs no GPU, display or EGL. Polygons are drawn as they are (not triangulated), with
their edges when a mesh is small enough for the tessellation to be seen, and flat
Lambert shading. Closed, outward-oriented meshes are back-face culled (matplotlib's
painter's sort then has far fewer faces to get wrong); any other mesh is drawn
two-sided, so a defect is shown rather than hidden.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spacemesh.mesh import PolygonMesh
from spacemesh.primitives import signed_volume
from spacemesh.topology import check_topology
from spacemesh.typed import FloatArray

#: Camera elevation and azimuth in degrees.
VIEW = (25.0, -60.0)
#: Meshes with more faces than this are drawn without edges.
MAX_EDGED_FACES = 3000
#: Face colour of each column kind (RGB).
COLORS = {
    "ours": (0.35, 0.55, 0.85),
    "psr_star": (0.90, 0.60, 0.30),
    "psr": (0.90, 0.70, 0.40),
    "bpa": (0.60, 0.75, 0.45),
    "gt": (0.70, 0.70, 0.70),
}


@dataclass(frozen=True)
class GalleryRow:
    """One shape of the gallery.

    Attributes
    ----------
    title : str
        Shown at the left of the row.
    points : (P, 3) float
        The input points.
    meshes : dict of str to PolygonMesh or None
        Method -> mesh (None when the method failed), all in the points' frame;
        include ``"gt"`` for the ground truth.
    """

    title: str
    points: FloatArray
    meshes: dict[str, PolygonMesh | None]


def short_title(title: str, width: int = 28) -> str:
    """A file-like title cut to fit a cell: the part after the last ``__``, at most ``width``."""
    name = title.rsplit("__", 1)[-1]
    return name if len(name) <= width else name[: width - 3] + "..."


def view_direction(elev: float = VIEW[0], azim: float = VIEW[1]) -> FloatArray:
    """(3,) unit vector from the scene towards matplotlib's camera."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def _draw_mesh(ax, mesh: PolygonMesh, color: tuple[float, float, float]) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    if mesh.n_faces == 0:
        return
    view = view_direction()
    light = view + np.array([0.3, 0.2, 0.5])
    light /= np.linalg.norm(light)
    normals = mesh.face_normals()  # (F, 3)
    report = check_topology(mesh)
    keep = np.ones(mesh.n_faces, dtype=bool)
    if report.is_closed_oriented_manifold and signed_volume(mesh) > 0:
        keep = normals @ view > -1e-9
        facing = normals @ light
    else:
        facing = np.abs(normals @ light)
    shade = 0.3 + 0.7 * np.clip(facing, 0.0, 1.0)  # (F,)
    faces = [f for f, k in zip(mesh.faces, keep, strict=True) if k]
    rgb = np.clip(np.outer(shade[keep], color), 0, 1)
    edged = mesh.n_faces <= MAX_EDGED_FACES
    ax.add_collection3d(
        Poly3DCollection(
            [mesh.vertices[f] for f in faces],
            facecolors=rgb,
            edgecolors=(0, 0, 0, 0.6) if edged else rgb,
            linewidths=0.2 if edged else 0.0,
        )
    )


def _frame(ax, title: str | None = None) -> None:
    ax.set(xlim=(-1, 1), ylim=(-1, 1), zlim=(-1, 1))
    ax.set_box_aspect((1, 1, 1), zoom=1.25)
    ax.view_init(elev=VIEW[0], azim=VIEW[1])
    ax.set_axis_off()
    if title:
        ax.set_title(title, fontsize=8)


def render_gallery(
    rows: Sequence[GalleryRow],
    path: str | Path,
    *,
    columns: Sequence[str] = ("points", "ours", "psr_star", "gt"),
    labels: dict[str, str] | None = None,
    title: str | None = None,
    cell_inches: float = 2.6,
) -> Path:
    """Render shapes (rows) by input points and methods (columns) into one PNG.

    Parameters
    ----------
    rows : sequence of GalleryRow
        Everything is expected in a [-1, 1] frame.
    path : path
    columns : sequence of str
        ``"points"`` or a key of the rows' ``meshes``; columns no row has are dropped.
    labels : dict, optional
        Column titles (default: the keys).
    title : str, optional
    cell_inches : float

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = labels or {}
    columns = [c for c in columns if c == "points" or any(c in r.meshes for r in rows)]
    n_rows, n_cols = max(len(rows), 1), max(len(columns), 1)
    fig = plt.figure(figsize=(cell_inches * n_cols, cell_inches * n_rows))
    view = view_direction()
    for i, row in enumerate(rows):
        for j, column in enumerate(columns):
            ax = fig.add_subplot(n_rows, n_cols, i * n_cols + j + 1, projection="3d")
            head = labels.get(column, column)
            if column == "points":
                p = np.asarray(row.points)
                depth = p @ view
                ax.scatter(
                    p[:, 0],
                    p[:, 1],
                    p[:, 2],
                    s=0.6,
                    c=depth,
                    cmap="viridis",
                    depthshade=False,
                    linewidths=0,
                )
                name = short_title(row.title)
                text = f"{head}\n{name}" if i == 0 else name
                text = f"{text} ({len(p)} points)"
            else:
                mesh = row.meshes.get(column)
                if mesh is None or mesh.n_faces == 0:
                    ax.text(0, 0, 0, "no mesh", ha="center", fontsize=9, color="red")
                    text = head if i == 0 else ""
                else:
                    _draw_mesh(ax, mesh, COLORS.get(column, (0.6, 0.6, 0.8)))
                    stats = f"V={mesh.n_vertices} F={mesh.n_faces}"
                    text = f"{head}\n{stats}" if i == 0 else stats
            _frame(ax, text)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
