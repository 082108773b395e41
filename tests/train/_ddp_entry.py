"""Entry point of the DDP test: one rank of a 2-process ``torchrun`` job (not a test)."""

import sys
from pathlib import Path

import torch

from spacemesh.nn.config import get_config
from spacemesh.train.loop import TrainOptions, train

if __name__ == "__main__":
    torch.set_num_threads(1)
    config = get_config("tiny").with_train(val_every=2, checkpoint_every=2, val_shapes=2,
                                           batch_size=2, connectivity_steps=1)
    train(TrainOptions(config=config, data=Path(sys.argv[1]), out=Path(sys.argv[2]), steps=2,
                       device="cpu", progress=False), log=lambda m: None)
