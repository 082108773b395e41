"""``spacemesh batch``: meshing many files at once on Ray Data.

- :mod:`~spacemesh.batch.inputs`: folders, globs and ``@LIST`` files, local or at any
  fsspec URL, expanded to :class:`~spacemesh.batch.inputs.BatchInput` (source, output name);
- :mod:`~spacemesh.batch.work`: :class:`~spacemesh.batch.work.Mesher`, one worker's
  loaded model meshing one input at a time into a manifest row;
- :mod:`~spacemesh.batch.manifest`: the manifest (JSON lines, and Parquet where pyarrow
  is installed), and which inputs a rerun skips;
- :mod:`~spacemesh.batch.ray_job`: :func:`~spacemesh.batch.ray_job.run_batch`, the run
  on Ray Data (the only module that imports ray: ``pip install 'spacemesh[batch]'``).

This package imports none of the others' modules into its namespace, so that importing
it needs neither ray nor onnxruntime.
"""
