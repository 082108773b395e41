"""Writing a model version's ``manifest.json``: whole, or section by section."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from spacemesh.runtime.repository import MANIFEST


def _json_safe(value: Any) -> Any:
    """``value`` with non-finite floats replaced by None (strict JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def write_manifest(directory: Path, manifest: dict[str, Any]) -> Path:
    """Write ``manifest.json`` (strict JSON, sorted keys, 2-space indent)."""
    path = Path(directory) / MANIFEST
    text = json.dumps(_json_safe(manifest), indent=2, sort_keys=True, allow_nan=False)
    path.write_text(text + "\n")
    return path


def update_manifest(directory: str | Path, **sections: Any) -> dict[str, Any]:
    """Replace top-level sections (e.g. ``metrics``) of an existing manifest.

    Parameters
    ----------
    directory : path
        The version folder.
    **sections
        Keys and their new values.

    Returns
    -------
    dict
        The new manifest.
    """
    path = Path(directory) / MANIFEST
    manifest = json.loads(path.read_text())
    manifest.update(sections)
    write_manifest(Path(directory), manifest)
    return manifest
