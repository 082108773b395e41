"""Aggregating rows into Table 1, the CSV and the histograms."""

from __future__ import annotations

import csv
import math

import numpy as np

from spacemesh.metrics.report import markdown_tables, plot_histograms, summarise, write_csv


def fake_rows():
    rows = []
    for i in range(2):
        for method, cd in (("ours", 1e-3), ("psr", 2e-3), ("gt", 5e-4)):
            rows.append(
                {
                    "shape_id": f"s{i}",
                    "method": method,
                    "category": "qem",
                    "status": "ok",
                    "seconds": 0.5,
                    "cd": cd,
                    "f1": 0.6,
                    "ecd": 0.02,
                    "ef1": 0.4,
                    "in": 0.3,
                    "n_vertices": 100,
                    "n_faces": 196,
                    "manifold": True,
                    "watertight": True,
                    "oriented": True,
                    "valid": True,
                    "components": 1,
                    "pieces": 1,
                    "genus": 0,
                    "topology": method != "psr" or i == 0,
                    "self_intersections": 0.01,
                    "edge_length_w1": 0.1,
                    "corner_angle_w1": 5.0,
                    "mean_edge_length": 0.2,
                    "mean_corner_angle": 60.0,
                    "degrees": "3:190 4:6",
                }
            )
    failed = dict(
        rows[0],
        method="bpa",
        status="failed: empty mesh",
        cd=math.nan,
        valid=False,
        manifold=False,
        watertight=False,
        oriented=False,
        degrees="",
    )
    return [*rows, failed]


def test_summary_and_tables(tmp_path):
    summary = summarise(fake_rows())
    assert list(summary) == ["ours", "psr", "bpa", "gt"]
    assert summary["ours"]["cd"] == 1e-3 and summary["ours"]["valid"] == 1.0
    assert summary["bpa"]["n_ok"] == 0 and summary["bpa"]["valid"] == 0.0
    assert math.isnan(summary["bpa"]["cd"])
    assert summary["ours"]["topology"] == 1.0 and summary["psr"]["topology"] == 0.5
    assert summary["ours"]["degrees"] == {3: 190 / 196, 4: 6 / 196}
    table = markdown_tables(summary)
    assert "| Ours | **1.00** |" in table  # CD in 1e-3, best value in bold
    assert "| GT (resampled) | 0.50 |" in table  # the reference row is never bold
    assert "| BPA | n/a |" in table and "0/1" in table
    path = write_csv(fake_rows(), tmp_path / "rows.csv")
    read = list(csv.DictReader(open(path)))
    assert len(read) == 7 and read[0]["valid"] == "1" and read[-1]["cd"] == ""


def test_histogram_png(tmp_path):
    rng = np.random.default_rng(0)
    distributions = {
        m: {
            "edge_lengths": [rng.uniform(0.01, 0.5, 50)],
            "corner_angles": [rng.uniform(10, 150, 90)],
        }
        for m in ("ours", "psr", "gt")
    }
    path = plot_histograms(distributions, summarise(fake_rows()), tmp_path / "h.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_topology_agreement_compares_pieces_and_genus_with_the_ground_truth():
    from spacemesh.examples import icosphere, torus_grid
    from spacemesh.metrics.compare import Reference, score_mesh
    from spacemesh.primitives import normalize

    sphere, _, _ = normalize(icosphere(2))
    torus, _, _ = normalize(torus_grid())
    reference = Reference.from_mesh(sphere)
    same = score_mesh(sphere, reference)
    assert (same["pieces"], same["genus"], same["topology"]) == (1, 0, True)
    other = score_mesh(torus, reference)
    assert (other["pieces"], other["genus"], other["topology"]) == (1, 1, False)

