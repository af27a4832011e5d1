"""A NumPy volume to a mesh with skelform's marching_cubes, as with scikit-image's.

    python examples/python/volume_to_mesh.py [out.ply]

Two balls and a bar on a 96³ lattice; the mesh is checked (one closed component of genus 0)
and written.
"""

import sys

import numpy as np

import skelform

z, y, x = np.mgrid[-1:1:96j, -1:1:96j, -1.5:1.5:96j]
balls = np.minimum(np.sqrt((x - 0.8) ** 2 + y**2 + z**2), np.sqrt((x + 0.8) ** 2 + y**2 + z**2))
bar = np.maximum(np.abs(x) - 0.8, np.sqrt(y**2 + z**2))
volume = np.minimum(balls - 0.5, bar - 0.15)

verts, faces, normals, values = skelform.marching_cubes(volume, 0.0, spacing=(2 / 95, 2 / 95, 3 / 95))
mesh = skelform.Mesh(verts, faces, normals)
report = mesh.check()
print(f"{len(verts)} vertices, {len(faces)} faces, components: "
      f"{[(c['closed'], c['genus']) for c in report['components']]}")
mesh.write(sys.argv[1] if len(sys.argv) > 1 else "volume.ply")
