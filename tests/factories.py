"""Small meshes made in code: tests never read ../shared/meshes."""

from spacemesh.examples import cube_quads, icosphere, prism, torus_grid

__all__ = ["BLOCK_TORCH", "cube_quads", "icosphere", "prism", "torus_grid"]


#: Python source that makes ``import torch`` fail in the process that runs it (prepend it
#: to a ``python -c`` script to show that code runs without torch).
BLOCK_TORCH = r"""
import sys


class BlockTorch:
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ImportError("torch is blocked in this process")
        return None


sys.meta_path.insert(0, BlockTorch())
"""
