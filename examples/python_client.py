"""Point cloud in, mesh out, with the Python client (pip install -e client).

Run from the repository root:  python examples/python_client.py [POINTS]
"""

import os
import sys

from spacemesh_client import Client, NoSurface

url = os.environ.get("SPACEMESH_URL", "http://localhost:8000")  # or grpc://localhost:8001
points = sys.argv[1] if len(sys.argv) > 1 else "examples/points.ply"

with Client(url) as client:
    try:
        mesh = client.generate(points, seed=int(os.environ.get("SEED", 0)))
    except NoSurface as error:  # every error kind has its exception class
        sys.exit(f"{error}: try another seed")
mesh.save("mesh.obj")  # polygons kept; .glb, .ply, .off, .json too
s = mesh.stats
print(f"mesh.obj: {len(mesh.vertices)} vertices, {len(mesh.faces)} faces "
      f"(sizes {s.face_degrees}), closed={s.closed}, oriented={s.oriented}, "
      f"genus {s.genus}, seed {mesh.seed}")
# How well it fits the points (the same report over REST and gRPC); more options:
# client.generate(points, start="points", target_vertices=500, samples=4, raw=False)
fit = s.fit or {}
print(f"fit: mean distance points->mesh {fit.get('points_to_mesh_mean_rel')} and "
      f"mesh->points {fit.get('mesh_to_points_mean_rel')} of the diagonal, "
      f"coverage {fit.get('coverage')}")
