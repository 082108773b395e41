"""Model repositories: ``NAME/VERSION/{encoder,denoiser,connectivity}.onnx + manifest.json``.

The layout follows Triton's model repository. ``manifest.json`` lists every file with its
sha256; :meth:`ModelRepository.load` checks them all before creating any session and
raises :class:`ModelRepositoryError` naming the file on a mismatch or a missing file.
onnxruntime sessions are created once per repository, with explicit thread counts.

The shipped default model lives in the source tree at ``models/spacemesh-small`` (its
highest version is loaded; version 1 is the training base of the later ones; see
:data:`DEFAULT_MODEL_DIR`); the ``SPACEMESH_MODEL`` environment variable overrides it.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from spacemesh.runtime.backend import OnnxBackend
from spacemesh.runtime.golden import SECTION as GOLDEN
from spacemesh.runtime.golden import golden_mismatches
from spacemesh.threads import resolve_threads

#: Manifest ``format`` value.
FORMAT = "spacemesh-model"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"
GRAPHS = ("encoder", "denoiser", "connectivity")

#: Name of the shipped model, and its folder in the source tree.
DEFAULT_MODEL_NAME = "spacemesh-small"
_SOURCE_ROOT = Path(__file__).resolve().parents[3]
_SHIPPED = _SOURCE_ROOT / "models" / DEFAULT_MODEL_NAME
#: Environment variable that overrides the default model path.
MODEL_ENV = "SPACEMESH_MODEL"


log = logging.getLogger(__name__)


class ModelRepositoryError(Exception):
    """A model repository is missing, incomplete, or does not match its manifest."""


def default_model_dir() -> Path:
    """``$SPACEMESH_MODEL`` if set, else the shipped ``models/spacemesh-small``."""
    override = os.environ.get(MODEL_ENV)
    return Path(override) if override else _SHIPPED


#: The default model folder (resolved at import; use :func:`default_model_dir` to re-read
#: the environment).
DEFAULT_MODEL_DIR = default_model_dir()


def resolve_version_dir(path: str | Path) -> Path:
    """The version folder holding ``manifest.json``.

    Parameters
    ----------
    path : path
        A version folder, a model folder (its highest numeric version is taken), or a
        repository root holding exactly one model.

    Returns
    -------
    Path
    """
    path = Path(path)
    if (path / MANIFEST).is_file():
        return path
    if not path.is_dir():
        raise ModelRepositoryError(f"model repository {path} does not exist")
    versions = sorted(
        (int(p.name), p) for p in path.iterdir() if p.is_dir() and p.name.isdigit()
        and (p / MANIFEST).is_file()
    )
    if versions:
        return versions[-1][1]
    models = [p for p in path.iterdir() if p.is_dir()]
    if len(models) == 1:
        return resolve_version_dir(models[0])
    raise ModelRepositoryError(f"no {MANIFEST} found under {path}")


def sha256_file(path: str | Path) -> str:
    """Hex sha256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def verify_files(directory: Path, manifest: dict[str, Any]) -> None:
    """Check that every file the manifest lists exists and has its sha256.

    Raises
    ------
    ModelRepositoryError
    """
    files = manifest.get("files")
    if not isinstance(files, dict) or not files:
        raise ModelRepositoryError(f"{directory / MANIFEST} lists no files")
    for graph in GRAPHS:
        if graph not in manifest.get("graphs", {}):
            raise ModelRepositoryError(f"{directory / MANIFEST} has no {graph} graph")
    for name, entry in files.items():
        path = directory / name
        if not path.is_file():
            raise ModelRepositoryError(f"model file {path} is missing")
        actual = sha256_file(path)
        if actual != entry.get("sha256"):
            raise ModelRepositoryError(
                f"model file {path} does not match its manifest: sha256 {actual}, "
                f"expected {entry.get('sha256')}"
            )


def verified_manifest(directory: str | Path) -> dict[str, Any]:
    """The manifest of a version folder whose files all match it (:func:`verify_files`).

    Raises
    ------
    ValueError
        No readable manifest, or a file missing or not matching it.
    """
    directory = Path(directory)
    try:
        manifest = json.loads((directory / MANIFEST).read_text())
        verify_files(directory, manifest)
    except (ModelRepositoryError, OSError, ValueError) as error:
        raise ValueError(str(error)) from error
    return manifest


#: onnxruntime's intra-op threads of a served model's sessions: one, the only count at
#: which its kernels sum in a fixed order (parallelism comes from running batch items at
#: once, :class:`~spacemesh.runtime.backend.OnnxBackend`).
DETERMINISTIC_INTRA_OP_THREADS = 1


@dataclass(frozen=True)
class SessionOptions:
    """onnxruntime threading and providers.

    Attributes
    ----------
    intra_op_threads : int
        Threads inside one operator (0 lets onnxruntime choose: all cores).
    inter_op_threads : int
        Threads across independent operators.
    providers : tuple of str
    """

    intra_op_threads: int = 0
    inter_op_threads: int = 1
    providers: tuple[str, ...] = ("CPUExecutionProvider",)


def create_session(path: Path, options: SessionOptions):
    """An onnxruntime session for one graph.

    Idle pool threads sleep instead of spinning (``allow_spinning = 0``): on a loaded
    machine a spinning pool takes the cores that the other work needs.
    """
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = options.intra_op_threads
    so.inter_op_num_threads = options.inter_op_threads
    so.add_session_config_entry("session.intra_op.allow_spinning", "0")
    so.add_session_config_entry("session.inter_op.allow_spinning", "0")
    so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    so.log_severity_level = 3
    return ort.InferenceSession(str(path), sess_options=so, providers=list(options.providers))


class ModelRepository:
    """A loaded, verified model: its manifest and one onnxruntime session per graph.

    Use :meth:`load`. Attributes: ``path`` (the version folder), ``manifest`` (dict),
    ``backend`` (:class:`spacemesh.runtime.backend.OnnxBackend`).
    """

    def __init__(self, path: Path, manifest: dict[str, Any], backend: OnnxBackend) -> None:
        self.path = path
        self.manifest = manifest
        self.backend = backend

    @classmethod
    def load(
        cls,
        path: str | Path | None = None,
        *,
        threads: int = 0,
        providers: tuple[str, ...] = ("CPUExecutionProvider",),
        verify: bool = True,
        golden: bool = True,
    ) -> ModelRepository:
        """Read and verify a model repository, and create its sessions.

        Parameters
        ----------
        path : path, optional
            Version folder, model folder or repository root (see
            :func:`resolve_version_dir`); default :func:`default_model_dir`.
        threads : int
            Threads that run the items of a batch at once (0: one per core this process
            may use, :func:`spacemesh.threads.resolve_threads`). Every graph call runs
            one item on one onnxruntime thread, so outputs are the same to the bit
            whatever this count (:class:`~spacemesh.runtime.backend.OnnxBackend`).
        providers : tuple of str
            onnxruntime execution providers.
        verify : bool
            Check the sha256 of every file (on by default).
        golden : bool
            Run the golden check (:meth:`check_golden`; on by default).

        Returns
        -------
        ModelRepository

        Raises
        ------
        ModelRepositoryError
            Missing folder, manifest or file, unknown format, a sha256 mismatch, or
            outputs that differ from the manifest's golden section.
        """
        directory = resolve_version_dir(path if path is not None else default_model_dir())
        try:
            manifest = json.loads((directory / MANIFEST).read_text())
        except (OSError, ValueError) as error:
            raise ModelRepositoryError(f"cannot read {directory / MANIFEST}: {error}") from error
        if manifest.get("format") != FORMAT:
            raise ModelRepositoryError(f"{directory / MANIFEST} is not a {FORMAT} manifest")
        if int(manifest.get("format_version", 0)) > FORMAT_VERSION:
            raise ModelRepositoryError(
                f"{directory / MANIFEST} has format version {manifest['format_version']}; "
                f"this runtime reads up to {FORMAT_VERSION}"
            )
        if verify:
            verify_files(directory, manifest)
        options = SessionOptions(DETERMINISTIC_INTRA_OP_THREADS, 1, tuple(providers))
        sessions = {
            g: create_session(directory / manifest["graphs"][g]["file"], options) for g in GRAPHS
        }
        backend = OnnxBackend(**sessions, workers=resolve_threads(threads))
        repository = cls(directory, manifest, backend)
        if golden:
            repository.check_golden()
        return repository

    def check_golden(self) -> None:
        """Run the graphs on the manifest's golden input and compare their outputs
        (:mod:`spacemesh.runtime.golden`). A manifest without the section (exported
        before it existed) passes with a warning.

        Raises
        ------
        ModelRepositoryError
            Naming every graph output outside the tolerance, and by how much.
        """
        if GOLDEN not in self.manifest:
            log.warning("%s has no golden section: the graphs' outputs are not checked "
                        "(re-export, or python -m spacemesh.export.golden %s)",
                        self.path / MANIFEST, self.path)
            return
        try:
            problems = golden_mismatches(self.backend, self.manifest)
        except Exception as error:  # a graph that cannot even run on the golden input
            raise ModelRepositoryError(f"model {self.path} fails its golden check: "
                                       f"{type(error).__name__}: {error}") from error
        if problems:
            raise ModelRepositoryError(f"model {self.path} fails its golden check: "
                                       + "; ".join(problems))

    @property
    def name(self) -> str:
        """Model name (e.g. ``spacemesh-small``)."""
        return str(self.manifest["name"])

    @property
    def version(self) -> str:
        """Model version (the version folder's name)."""
        return str(self.manifest["version"])

    @property
    def config(self) -> dict[str, Any]:
        """The training configuration (a dict of :class:`spacemesh.nn.config.ModelConfig`)."""
        return self.manifest["config"]

    def __repr__(self) -> str:
        return f"ModelRepository({str(self.path)!r}, name={self.name!r}, version={self.version})"
