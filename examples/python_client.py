"""Point cloud in, mesh out, with the Python client (pip install -e client).

    python examples/python_client.py [POINTS]     (SPACEMESH_URL, SEED to change)
"""

import os
import sys
from pathlib import Path

from spacemesh_client import Client, NoSurface

url = os.environ.get("SPACEMESH_URL", "http://localhost:8000")
points = sys.argv[1] if len(sys.argv) > 1 else Path(__file__).with_name("points.ply")

with Client(url) as client:  # grpc://localhost:8001 works the same
    try:
        mesh = client.generate(points, seed=int(os.environ.get("SEED", 7)))
    except NoSurface as error:  # every error kind has its exception class
        sys.exit(f"{error}: try another seed")
    mesh.save("mesh.obj")  # polygons kept; .glb, .ply, .off, .json too
    s = mesh.stats
    print(f"mesh.obj: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces "
          f"(sizes {s.face_degrees}), closed={s.closed}, oriented={s.oriented}, "
          f"genus {s.genus}, seed {mesh.seed}")
