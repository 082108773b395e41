"""The web page at ``/``: generate, inspect, repair and download meshes in a browser.

Everything the page loads comes from the service itself (no CDN, works offline):

``GET /``
    ``static/index.html`` (the page, ``static/app.js`` and ``static/app.css``).
``GET /static/...``
    The page's assets and the vendored three.js (``static/vendor/three``, with its
    licence).
``GET /static/config.json``
    What the page offers, from the service's own tables so it never drifts: the
    options of each route (their OpenAPI parameters, :mod:`spacemesh_service.options`),
    output and input formats, the automatic repair regions and the request limits.
``POST /ui/preview``
    Multipart ``file`` and ``kind`` (``points`` or ``mesh``): the file read by the same
    readers and limits as ``/generate`` and ``/repair`` (so face indices picked on the
    page are the server's), as JSON ``{"points": [...]}`` (at most
    :data:`PREVIEW_POINTS`) or ``{"vertices": [...], "faces": [[...], ...]}``.

The page and its assets are open like the health routes; ``/ui/preview`` and the mesh
routes need the API key when keys are on (the page sends the key typed in its key
field as ``Authorization: Bearer``, keeping it only in memory). ``--no-ui`` leaves all
of this out.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from fastapi import FastAPI, Request
from fastapi.responses import FileResponse, JSONResponse
from fastapi.staticfiles import StaticFiles
from starlette.datastructures import UploadFile

from spacemesh_service import problems as P
from spacemesh_service.engine import Engine
from spacemesh_service.inputs import (
    INPUT_FORMATS,
    MESH_FORMATS,
    UploadRules,
    read_cloud_upload,
    read_mesh_upload,
)
from spacemesh_service.openapi import UI_PREVIEW_RESPONSES
from spacemesh_service.options import GENERATE_ROUTE_OPTIONS, REPAIR_ROUTE_OPTIONS
from spacemesh_service.outputs import OUTPUT_FORMATS
from spacemesh_service.problems import Problem

#: The page's files (package data of ``spacemesh-service``).
STATIC = Path(__file__).with_name("static")
#: Most points ``/ui/preview`` returns (an evenly strided subset of larger clouds).
PREVIEW_POINTS = 20_000
#: What ``kind`` of file ``/ui/preview`` reads.
PREVIEW_KINDS = ("points", "mesh")


def _auto_regions() -> list[str]:
    """The automatic repair regions of this build (``{"auto": mode}``), if any."""
    from spacemesh.repair import region

    return list(getattr(region, "AUTO_MODES", ()))


def page_config(engine: Engine) -> dict[str, Any]:
    """``/static/config.json``: the options, formats and limits the page offers."""
    return {
        "routes": {"generate": "/generate", "generate_stream": "/generate/stream",
                   "repair": "/repair", "repair_stream": "/repair/stream",
                   "preview": "/ui/preview"},
        "generate_options": [o.parameter() for o in GENERATE_ROUTE_OPTIONS],
        "repair_options": [o.parameter() for o in REPAIR_ROUTE_OPTIONS],
        "output_formats": list(OUTPUT_FORMATS),
        "input_formats": {"points": list(INPUT_FORMATS), "mesh": list(MESH_FORMATS)},
        "auto_regions": _auto_regions(),
        "limits": engine.settings.limits(),
        "preview_points": PREVIEW_POINTS,
    }


def _flat(values: np.ndarray) -> list[float]:
    return np.asarray(values, dtype=np.float64).reshape(-1).tolist()


def preview(data: bytes, filename: str | None, kind: str, limits: Any,
            rules: UploadRules | None = None) -> dict[str, Any]:
    """What ``/ui/preview`` answers for one file (run in a worker thread); ``count`` is
    the file's points, those shown a subset of the ones ``/generate`` would use."""
    if kind == "mesh":
        mesh, source = read_mesh_upload(data, filename, limits, rules)
        return {"kind": "mesh", "source": source, "vertices": _flat(mesh.vertices),
                "faces": [list(map(int, face)) for face in mesh.faces]}
    points, _, source, count = read_cloud_upload(data, filename, limits, rules)
    step = max(1, -(-len(points) // PREVIEW_POINTS))
    return {"kind": "points", "source": source,
            "count": len(points) if count is None else count,
            "points": _flat(points[::step])}


def install_ui(app: FastAPI, engine: Engine, limited: Callable[[Request, int], Request]
               ) -> None:
    """Add the page, its assets, its config and ``/ui/preview`` to ``app``.

    Parameters
    ----------
    app : FastAPI
    engine : Engine
    limited : callable
        ``limited(request, max_bytes)``: the request with its body bounded (413 beyond),
        as for the mesh routes.
    """
    settings = engine.settings

    @app.get("/", include_in_schema=False)
    async def page() -> FileResponse:
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    @app.get("/static/config.json", include_in_schema=False)
    async def config() -> JSONResponse:
        return JSONResponse(page_config(engine), headers={"Cache-Control": "no-cache"})

    @app.post("/ui/preview", tags=["ui"], summary="Read a file as the page shows it",
              responses=UI_PREVIEW_RESPONSES)
    async def ui_preview(request: Request) -> JSONResponse:
        """Multipart `file` and `kind` (`points` or `mesh`): the file read as `/generate`
        (points) or `/repair` (mesh) read it, as JSON, for the web page."""
        form = await limited(request, settings.max_upload_bytes).form(max_files=1,
                                                                      max_fields=4)
        try:
            upload, kind = form.get("file"), form.get("kind", "points")
            if not isinstance(upload, UploadFile):
                raise Problem(P.MALFORMED_INPUT, "the multipart body has no file field 'file'")
            if kind not in PREVIEW_KINDS:
                raise Problem(P.INVALID_PARAMETER,
                              f"kind is one of {', '.join(PREVIEW_KINDS)}, not {kind!r}")
            data, filename = await upload.read(), upload.filename
        finally:
            await form.close()
        body = await engine.parsing.run(preview, data, filename, kind, engine.read_limits,
                                        UploadRules.from_settings(settings))
        return JSONResponse(body)

    app.mount("/static", StaticFiles(directory=STATIC), name="static")
