"""Dataset statistics: counts and histograms of vertices, faces, face degrees, genus."""

from __future__ import annotations

import io
import json
import zipfile
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from spacemesh.data.shards import MANIFEST


@dataclass
class DatasetStats:
    """Per-shape numbers of one dataset, gathered from its shards.

    Attributes
    ----------
    n_vertices, n_faces, genus : (N,) int64
    degrees : Counter
        Face degree -> number of faces over the whole dataset.
    concave_sharp : (N,) bool
    splits : Counter
    manifest : dict
    """

    n_vertices: np.ndarray
    n_faces: np.ndarray
    genus: np.ndarray
    concave_sharp: np.ndarray
    degrees: Counter = field(default_factory=Counter)
    splits: Counter = field(default_factory=Counter)
    manifest: dict = field(default_factory=dict)

    @property
    def count(self) -> int:
        """Number of shapes."""
        return len(self.n_vertices)

    def summary(self) -> dict:
        """JSON-ready summary (counts, ranges, fractions, rejections)."""
        count = max(self.count, 1)
        positive = self.genus > 0
        return {
            "shapes": self.count,
            "style": self.manifest.get("style"),
            "splits": dict(sorted(self.splits.items())),
            "vertices": _range(self.n_vertices),
            "faces": _range(self.n_faces),
            "face_degrees": {str(k): v for k, v in sorted(self.degrees.items())},
            "genus": {str(k): int(v) for k, v in sorted(Counter(self.genus.tolist()).items())},
            "fraction_genus_positive": float(positive.sum() / count),
            "fraction_concave_sharp": float(self.concave_sharp.sum() / count),
            "fraction_genus_or_concave": float((positive | self.concave_sharp).sum() / count),
            "rejections": self.manifest.get("rejections", {}),
            "attempts": self.manifest.get("counts", {}).get("attempts"),
        }


def _range(values: np.ndarray) -> dict:
    if values.size == 0:
        return {}
    return {
        "min": int(values.min()),
        "median": float(np.median(values)),
        "mean": float(values.mean()),
        "max": int(values.max()),
    }


def collect_stats(directory: str | Path) -> DatasetStats:
    """Read the statistics of a dataset folder (only face sizes and records are loaded).

    Parameters
    ----------
    directory : path
        A folder with ``manifest.json``.

    Returns
    -------
    DatasetStats
    """
    directory = Path(directory)
    manifest_path = directory / MANIFEST
    if not manifest_path.is_file():
        raise FileNotFoundError(f"{directory} has no {MANIFEST}")
    manifest = json.loads(manifest_path.read_text())
    n_vertices, n_faces, genus, concave = [], [], [], []
    degrees: Counter = Counter()
    splits: Counter = Counter()
    for entry in manifest["shards"]:
        with zipfile.ZipFile(directory / entry["file"]) as archive:
            records = json.loads(archive.read("records.json"))
            sizes = np.lib.format.read_array(io.BytesIO(archive.read("face_sizes.npy")))
        values, counts = np.unique(sizes, return_counts=True)
        degrees.update({int(v): int(c) for v, c in zip(values, counts, strict=True)})
        for r in records:
            n_vertices.append(r["n_vertices"])
            n_faces.append(r["n_faces"])
            genus.append(r["genus"])
            concave.append(bool(r.get("features", {}).get("concave_sharp", False)))
            splits[r["split"]] += 1
    return DatasetStats(
        n_vertices=np.asarray(n_vertices, dtype=np.int64),
        n_faces=np.asarray(n_faces, dtype=np.int64),
        genus=np.asarray(genus, dtype=np.int64),
        concave_sharp=np.asarray(concave, dtype=bool),
        degrees=degrees,
        splits=splits,
        manifest=manifest,
    )


def text_histogram(values: np.ndarray, bins: int = 10, width: int = 40) -> list[str]:
    """Rows ``"lo - hi | ##### count"`` of a histogram of integer values.

    Parameters
    ----------
    values : (N,) array
    bins : int
    width : int
        Characters of the longest bar.

    Returns
    -------
    list of str
    """
    if values.size == 0:
        return ["(no shapes)"]
    counts, edges = np.histogram(values, bins=bins)
    top = max(int(counts.max()), 1)
    return [
        f"{edges[i]:8.0f} - {edges[i + 1]:8.0f} | {'#' * round(width * c / top):<{width}} {c}"
        for i, c in enumerate(counts)
    ]


def bar_rows(counter: dict, width: int = 40) -> list[str]:
    """Rows ``"key | ##### count"`` of a categorical histogram."""
    if not counter:
        return ["(none)"]
    top = max(counter.values())
    return [
        f"{k!s:>8} | {'#' * round(width * v / top):<{width}} {v}"
        for k, v in sorted(counter.items())
    ]


def plot_stats(stats: DatasetStats, path: str | Path, title: str | None = None) -> Path:
    """Write the four histograms (vertices, faces, face degrees, genus) as one PNG.

    Parameters
    ----------
    stats : DatasetStats
    path : path
        The PNG file to write.
    title : str, optional

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    axes[0, 0].hist(stats.n_vertices, bins=30, color="#4477aa")
    axes[0, 0].set(title="vertices per shape", xlabel="vertices", ylabel="shapes")
    axes[0, 1].hist(stats.n_faces, bins=30, color="#66ccee")
    axes[0, 1].set(title="faces per shape", xlabel="faces", ylabel="shapes")
    degree_keys = sorted(stats.degrees)
    shown = [k for k in degree_keys if k <= 12]
    labels = [str(k) for k in shown]
    values = [stats.degrees[k] for k in shown]
    if any(k > 12 for k in degree_keys):
        labels.append(">12")
        values.append(sum(v for k, v in stats.degrees.items() if k > 12))
    axes[1, 0].bar(labels, values, color="#228833")
    axes[1, 0].set(title="face degrees (all faces)", xlabel="sides", ylabel="faces")
    genus_counts = Counter(stats.genus.tolist())
    axes[1, 1].bar(
        [str(k) for k in sorted(genus_counts)],
        [genus_counts[k] for k in sorted(genus_counts)],
        color="#ee6677",
    )
    axes[1, 1].set(title="genus", xlabel="genus", ylabel="shapes")
    style = stats.manifest.get("style", "")
    fig.suptitle(title or f"{stats.count} shapes, style {style}")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def plot_gallery(records, path: str | Path, columns: int = 4, title: str | None = None) -> Path:
    """Render a few stored shapes (polygon edges drawn) into one PNG.

    Parameters
    ----------
    records : sequence of MeshRecord
    path : path
    columns : int
    title : str, optional

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    records = list(records)
    rows = max(1, -(-len(records) // columns))
    fig = plt.figure(figsize=(3.2 * columns, 3.2 * rows))
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    for i, record in enumerate(records):
        ax = fig.add_subplot(rows, columns, i + 1, projection="3d")
        mesh = record.mesh
        shade = 0.35 + 0.6 * np.clip(mesh.face_normals() @ light, 0, 1)  # (F,)
        polygons = [mesh.vertices[f] for f in mesh.faces]
        colors = np.stack([shade * 0.55, shade * 0.7, shade * 0.9, np.ones_like(shade)], axis=1)
        ax.add_collection3d(
            Poly3DCollection(polygons, facecolors=colors, edgecolors="k", linewidths=0.25)
        )
        ax.set(xlim=(-1, 1), ylim=(-1, 1), zlim=(-1, 1))
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=25, azim=-60)
        ax.set_axis_off()
        degrees = ", ".join(f"{k}:{v}" for k, v in sorted(mesh.degree_histogram().items())[:4])
        ax.set_title(f"V={mesh.n_vertices} g={record.genus}\n{degrees}", fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return Path(path)
