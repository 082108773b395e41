"""Per-shape metric rows into the paper's Table 1 (markdown), a CSV, and histogram PNGs.

A *row* is one (shape, method) pair: ``shape_id``, ``method``, ``category``, ``status``
(``ok``, or why the method produced no mesh), ``seconds`` and the keys of
:data:`spacemesh.metrics.compare.METRIC_KEYS`.

Aggregation (:func:`summarise`), per method:

- CD, F1, ECD, EF1, IN, #V, #F, self-intersections, and the Wasserstein distances are
  means over the shapes where the method produced a mesh with a surface (``n_ok``);
- the manifold, watertight, oriented and valid *rates* are over all shapes (a failure
  counts as invalid);
- the face-degree histogram is pooled over all faces of all its meshes.

Table 1 prints CD in 1e-3, ECD in 1e-2 and IN in percent, like the paper.
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from spacemesh.metrics.compare import METRIC_KEYS

#: Leading columns of a row, before the metrics.
ROW_KEYS = ("shape_id", "method", "category", "status", "seconds")
#: Display names of methods, in table order (unknown methods follow, as given).
METHOD_LABELS = {
    "ours": "Ours",
    "ours_s4": "Ours (samples=4)",
    "ours_raw": "Ours (raw)",
    "ours_paper": "Ours (paper: raw, start=noise)",
    "ours_gt": "Ours (target = GT count)",
    "ours_denoise_low": "Ours (start_time = 0.02)",
    "ours_denoise": "Ours (start_time = 0.05)",
    "ours_gt_denoise": "Ours (target = GT count, start_time = 0.05)",
    "ours_no_fit": "Ours without the vertex fit",
    "ours_no_flips": "Ours without edge flips",
    "ours_no_sharp": "Ours without sharp features",
    "ours_normals": "Ours (true normals)",
    "psr": "PSR",
    "psr_star": "PSR*",
    "psr_star_gt": "PSR* (GT count)",
    "psr_true": "PSR* (true normals)",
    "psr_true_gt": "PSR* (true normals, GT count)",
    "bpa": "BPA",
    "gt": "GT (resampled)",
}
#: Mean metrics (over shapes with a mesh).
MEAN_KEYS = (
    "cd",
    "f1",
    "ecd",
    "ef1",
    "in",
    "n_vertices",
    "n_faces",
    "self_intersections",
    "edge_length_w1",
    "corner_angle_w1",
    "seconds",
)
#: Rates (over all shapes).
RATE_KEYS = ("manifold", "watertight", "oriented", "valid", "topology")
#: Whether lower is better, for the metrics that get a bold best value.
LOWER_IS_BETTER = {
    "cd": True,
    "f1": False,
    "ecd": True,
    "ef1": False,
    "in": True,
    "self_intersections": True,
    "edge_length_w1": True,
    "corner_angle_w1": True,
    "valid": False,
    "topology": False,
}


def method_label(method: str) -> str:
    """The display name of a method."""
    return METHOD_LABELS.get(method, method)


def method_order(methods: Iterable[str]) -> list[str]:
    """Methods in table order: known ones first (ours, PSR, PSR*, BPA, GT), then the rest."""
    unique = list(dict.fromkeys(methods))
    known = [m for m in METHOD_LABELS if m in unique]
    return known + [m for m in unique if m not in METHOD_LABELS]


def write_csv(rows: Sequence[dict[str, Any]], path: str | Path) -> Path:
    """Write rows as CSV with the columns of :data:`ROW_KEYS` + :data:`METRIC_KEYS`.

    Parameters
    ----------
    rows : sequence of dict
    path : path

    Returns
    -------
    Path
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    columns = list(ROW_KEYS) + list(METRIC_KEYS)
    extra = sorted({k for r in rows for k in r} - set(columns))
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns + extra, extrasaction="ignore")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _csv_value(row.get(k)) for k in columns + extra})
    return path


def _csv_value(value: Any) -> Any:
    if isinstance(value, float):
        return "" if math.isnan(value) else f"{value:.6g}"
    if isinstance(value, bool | np.bool_):
        return int(value)
    return "" if value is None else value


def _mean(values: list[float]) -> float:
    finite = [float(v) for v in values if v is not None and not math.isnan(float(v))]
    return float(np.mean(finite)) if finite else float("nan")


def summarise(rows: Sequence[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Aggregate rows per method (see the module doc).

    Parameters
    ----------
    rows : sequence of dict

    Returns
    -------
    dict
        Method -> ``n``, ``n_ok``, the means of :data:`MEAN_KEYS`, the rates of
        :data:`RATE_KEYS` (fractions), ``median_cd`` and ``degrees`` (face degree ->
        fraction of all faces).
    """
    out: dict[str, dict[str, Any]] = {}
    for method in method_order(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        ok = [r for r in mine if r.get("status") == "ok" and not math.isnan(_float(r.get("cd")))]
        summary: dict[str, Any] = {"n": len(mine), "n_ok": len(ok)}
        for key in MEAN_KEYS:
            summary[key] = _mean([_float(r.get(key)) for r in (mine if key == "seconds" else ok)])
        for key in RATE_KEYS:
            summary[key] = float(np.mean([bool(r.get(key)) for r in mine])) if mine else math.nan
        cds = [_float(r.get("cd")) for r in ok]
        summary["median_cd"] = float(np.median(cds)) if cds else math.nan
        degrees: Counter[int] = Counter()
        for r in ok:
            degrees.update(parse_degrees(r.get("degrees", "")))
        total = sum(degrees.values())
        summary["degrees"] = {k: v / total for k, v in sorted(degrees.items())} if total else {}
        out[method] = summary
    return out


def _float(value: Any) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        return float("nan")


def parse_degrees(text: str) -> dict[int, int]:
    """``"3:120 4:8"`` -> ``{3: 120, 4: 8}``."""
    pairs = (item.split(":") for item in str(text).split() if ":" in item)
    return {int(k): int(v) for k, v in pairs}


def _fmt(value: float, digits: int = 2) -> str:
    return "n/a" if value is None or math.isnan(value) else f"{value:.{digits}f}"


def _best(summary: dict[str, dict[str, Any]], key: str) -> float | None:
    values = [s[key] for m, s in summary.items() if m != "gt" and not math.isnan(s[key])]
    if not values:
        return None
    return min(values) if LOWER_IS_BETTER[key] else max(values)


def _cell(
    summary: dict[str, dict[str, Any]], method: str, key: str, scale: float = 1.0, digits: int = 2
) -> str:
    value = summary[method][key]
    text = _fmt(value * scale, digits)
    best = _best(summary, key) if key in LOWER_IS_BETTER and method != "gt" else None
    return f"**{text}**" if best is not None and value == best else text


def format_degrees(fractions: dict[int, float], top: int = 4) -> str:
    """Pooled degree fractions as ``"3: 62%, 4: 30%, 5+: 8%"``."""
    if not fractions:
        return "n/a"
    items = sorted(fractions.items())
    head, tail = items[: top - 1], items[top - 1 :]
    parts = [f"{k}: {100 * v:.0f}%" for k, v in head]
    if tail:
        label = f"{tail[0][0]}" if len(tail) == 1 else f"{tail[0][0]}+"
        parts.append(f"{label}: {100 * sum(v for _, v in tail):.0f}%")
    return ", ".join(parts)


def markdown_tables(summary: dict[str, dict[str, Any]]) -> str:
    """Table 1 (accuracy) and the quality table (Fig. 9 statistics) as markdown.

    Parameters
    ----------
    summary : dict
        From :func:`summarise`.

    Returns
    -------
    str
    """
    lines = [
        "| Method | CD (1e-3) ↓ | F1 ↑ | ECD (1e-2) ↓ | EF1 ↑ | #V | #F | IN (%) ↓ | meshes |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for method, s in summary.items():
        lines.append(
            f"| {method_label(method)} | {_cell(summary, method, 'cd', 1e3)} "
            f"| {_cell(summary, method, 'f1')} | {_cell(summary, method, 'ecd', 1e2)} "
            f"| {_cell(summary, method, 'ef1')} | {_fmt(s['n_vertices'], 0)} "
            f"| {_fmt(s['n_faces'], 0)} | {_cell(summary, method, 'in', 100, 1)} "
            f"| {s['n_ok']}/{s['n']} |"
        )
    lines += [
        "",
        "| Method | valid % ↑ | topology % ↑ | manifold % | watertight % | oriented % "
        "| self-int. faces % ↓ "
        "| edge-length W1 ↓ | corner-angle W1 (deg) ↓ | median CD (1e-3) | face degrees "
        "| s/shape |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for method, s in summary.items():
        lines.append(
            f"| {method_label(method)} | {_cell(summary, method, 'valid', 100, 0)} "
            f"| {_cell(summary, method, 'topology', 100, 0)} "
            f"| {_fmt(100 * s['manifold'], 0)} | {_fmt(100 * s['watertight'], 0)} "
            f"| {_fmt(100 * s['oriented'], 0)} "
            f"| {_cell(summary, method, 'self_intersections', 100, 2)} "
            f"| {_cell(summary, method, 'edge_length_w1', 1, 3)} "
            f"| {_cell(summary, method, 'corner_angle_w1', 1, 1)} "
            f"| {_fmt(1e3 * s['median_cd'], 2)} | {format_degrees(s['degrees'])} "
            f"| {_fmt(s['seconds'], 2)} |"
        )
    return "\n".join(lines) + "\n"


def plot_histograms(
    distributions: dict[str, dict[str, list[np.ndarray]]],
    summary: dict[str, dict[str, Any]],
    path: str | Path,
    *,
    title: str | None = None,
) -> Path:
    """Fig. 9: edge-length and corner-angle histograms per method, self-intersections, degrees.

    Parameters
    ----------
    distributions : dict
        Method -> ``{"edge_lengths": [arrays], "corner_angles": [arrays]}`` pooled over
        shapes (lengths in the [-1, 1] frame, angles in degrees).
    summary : dict
        From :func:`summarise` (self-intersection means and face degrees).
    path : path
    title : str, optional

    Returns
    -------
    Path
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = method_order(distributions)
    colors = {m: "k" if m == "gt" else plt.cm.tab10(i) for i, m in enumerate(methods)}
    fig, axes = plt.subplots(1, 4, figsize=(19, 4.2))
    length_bins = np.geomspace(1e-3, 2.0, 61)
    angle_bins = np.linspace(0.0, 180.0, 61)
    for method in methods:
        style = {
            "color": colors[method],
            "histtype": "step",
            "linewidth": 2.0 if method in ("gt", "ours") else 1.2,
            "label": "GT" if method == "gt" else method_label(method),
        }
        lengths = _concat(distributions[method].get("edge_lengths", []))
        angles = _concat(distributions[method].get("corner_angles", []))
        if len(lengths):  # each histogram sums to 1 (fractions, also on the log axis)
            axes[0].hist(
                np.clip(lengths, length_bins[0], length_bins[-1]),
                bins=length_bins,
                weights=np.full(len(lengths), 1.0 / len(lengths)),
                **style,
            )
        if len(angles):
            axes[1].hist(
                np.clip(angles, 0, 180),
                bins=angle_bins,
                weights=np.full(len(angles), 1.0 / len(angles)),
                **style,
            )
    axes[0].set(
        xscale="log",
        xlabel="edge length ([-1, 1] frame)",
        ylabel="fraction of edges",
        title="Edge lengths",
    )
    axes[1].set(
        xlabel="corner angle (degrees)", ylabel="fraction of corners", title="Corner angles"
    )
    axes[0].legend(fontsize=8)
    shown = [m for m in methods if m in summary]
    x = np.arange(len(shown))
    axes[2].bar(
        x,
        [100 * _nan0(summary[m]["self_intersections"]) for m in shown],
        color=[colors[m] for m in shown],
    )
    axes[2].set(xticks=x, title="Faces with self-intersections (%)")
    axes[2].set_xticklabels(
        [method_label(m).replace(" (resampled)", "") for m in shown], fontsize=8
    )
    degrees = sorted({d for m in shown for d in summary[m]["degrees"]})
    degrees = [d for d in degrees if d <= 8] or [3]
    width = 0.8 / max(len(shown), 1)
    for i, m in enumerate(shown):
        fractions = summary[m]["degrees"]
        axes[3].bar(
            np.arange(len(degrees)) + i * width,
            [100 * fractions.get(d, 0.0) for d in degrees],
            width,
            color=colors[m],
            label=method_label(m),
        )
    axes[3].set(
        xticks=np.arange(len(degrees)) + 0.4 - width / 2, ylabel="% of faces", title="Face degrees"
    )
    axes[3].set_xticklabels([str(d) for d in degrees])
    axes[3].legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return path


def _concat(arrays: list[np.ndarray]) -> np.ndarray:
    return np.concatenate(arrays) if arrays else np.zeros(0)


def _nan0(value: float) -> float:
    return 0.0 if math.isnan(value) else value
