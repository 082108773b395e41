"""Training logs: one CSV row per logged step, and PNG curves drawn from the CSV.

The CSV's columns are the union of the keys seen so far; when a row brings a new key the
file is rewritten with the wider header (rows are few: one per log interval).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path


class MetricsLog:
    """Append-only CSV of metric rows (resumable: existing rows are kept).

    Parameters
    ----------
    path : path
        The CSV file.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.rows: list[dict[str, float]] = []
        if self.path.is_file():
            with open(self.path, newline="") as handle:
                self.rows = [
                    {k: float(v) for k, v in row.items() if v not in ("", None)}
                    for row in csv.DictReader(handle)
                ]
        self.columns: list[str] = []
        for row in self.rows:
            self._extend(row)

    def _extend(self, row: dict) -> bool:
        new = [k for k in row if k not in self.columns]
        self.columns.extend(new)
        return bool(new)

    def truncate(self, step: int) -> None:
        """Drop rows after ``step`` (used when resuming from an older checkpoint)."""
        self.rows = [r for r in self.rows if r.get("step", 0) <= step]
        self._write_all()

    def append(self, row: dict[str, float]) -> None:
        """Add one row (a dict of numbers) and flush it to disk."""
        row = {k: float(v) for k, v in row.items()}
        self.rows.append(row)
        if self._extend(row) or not self.path.is_file():
            self._write_all()
        else:
            with open(self.path, "a", newline="") as handle:
                csv.DictWriter(handle, self.columns).writerow(row)

    def _write_all(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "w", newline="") as handle:
            writer = csv.DictWriter(handle, self.columns)
            writer.writeheader()
            writer.writerows(self.rows)


#: Curves drawn by :func:`plot_curves`, one panel each: (title, columns, log scale).
PANELS = (
    ("diffusion loss", ("train_epsilon", "train_mask", "val_epsilon", "val_mask"), True),
    ("connectivity loss", ("train_edge", "train_permutation", "val_edge", "val_permutation"),
     True),
    ("held-out connectivity (GT vertices)", ("val_edge_f1", "val_next_accuracy"), False),
)


def plot_curves(log: MetricsLog, path: str | Path) -> Path | None:
    """Draw the training curves of ``log`` into a PNG (None if matplotlib is missing).

    Parameters
    ----------
    log : MetricsLog
    path : path

    Returns
    -------
    Path or None
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover
        return None
    series = {
        column: [(r["step"], r[column]) for r in log.rows
                 if column in r and "step" in r and math.isfinite(r[column])]
        for _, columns, _ in PANELS for column in columns
    }
    # a connectivity-only run (on a base model) logs no diffusion losses: no empty panel
    panels = [p for p in PANELS if any(series[c] for c in p[1])] or list(PANELS)
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.6), squeeze=False)
    for ax, (title, columns, log_scale) in zip(axes[0], panels, strict=True):
        for column in columns:
            if series[column]:
                xs, ys = zip(*series[column], strict=True)
                ax.plot(xs, ys, label=column, marker="." if column.startswith("val") else None)
        ax.set_title(title)
        ax.set_xlabel("step")
        if log_scale and ax.lines:
            ax.set_yscale("log")
        if ax.lines:
            ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
