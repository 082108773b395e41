"""Training data: synthetic CSG shapes, importers, validation and shards.

- :mod:`~spacemesh.data.shapes`: random CAD-like solids (manifold3d CSG).
- :mod:`~spacemesh.data.styles`: tessellation styles (qem, planar, isotropic, quad).
- :mod:`~spacemesh.data.validate`: the strict validator every stored shape passes.
- :mod:`~spacemesh.data.normalize`: z-y-x ordering and the canonical stored form.
- :mod:`~spacemesh.data.shards`: the shard format, manifest and :func:`open_dataset`.
- :mod:`~spacemesh.data.synth`: parallel, resumable generation.
- :mod:`~spacemesh.data.importer`: folders of user meshes into the same format.
- :mod:`~spacemesh.data.stats`: dataset statistics and histograms.

Only :mod:`~spacemesh.data.shards` is needed to read a dataset; the rest needs the
``geometry`` extra (manifold3d, pymeshlab, matplotlib).
"""

from spacemesh.data.shards import Dataset, MeshRecord, open_dataset
from spacemesh.data.validate import validate_mesh

__all__ = ["Dataset", "MeshRecord", "open_dataset", "validate_mesh"]
