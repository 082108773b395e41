"""Training: batches, the loop, checkpoints, logs, data-parallel setup, evaluation.

- :mod:`~spacemesh.train.batching`: records to padded batches, augmentation.
- :mod:`~spacemesh.train.loop`: :func:`train` and the run folder layout.
- :mod:`~spacemesh.train.checkpoint`: ``weights_only`` checkpoints, resume.
- :mod:`~spacemesh.train.logging`: CSV metrics and PNG curves.
- :mod:`~spacemesh.train.distributed`: ``torchrun`` / DistributedDataParallel.
- :mod:`~spacemesh.train.evaluate`: held-out connectivity and pipeline metrics.
- :mod:`~spacemesh.train.toy`: a seconds-to-make toy dataset for tests.
"""
