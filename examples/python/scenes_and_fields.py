"""Scenes, formulas and Python functions meshed by skelform.

    python examples/python/scenes_and_fields.py [saucer.glb]

Run from the repository's root (it reads examples/*.toml).
"""

import sys

import numpy as np

import skelform

# A scene file, with an override of its resolution, and progress as it goes.
torus = skelform.load_scene("examples/torus.toml").mesh(
    resolution=96, progress=lambda phase, done, total: print(f"\r{phase} {done}/{total}", end="")
)
print(f"\n{torus}: genus {torus.check()['components'][0]['genus']}")

# A formula on NumPy arrays.
f = skelform.Formula("sqrt(x^2 + y^2 + z^2) - 0.8")
print("f on a line:", f.eval(np.linspace(-1, 1, 5), 0, 0))

# A Python function as the field: given an (N, 3) array, it returns N values.
def capsule(p):
    x, y, z = p.T
    t = np.clip(x, -0.5, 0.5)
    return np.sqrt((x - t) ** 2 + y**2 + z**2) - 0.3

blob = skelform.mesh(capsule, ((-1, -0.5, -0.5), (1, 0.5, 0.5)), resolution=64)
print(blob, blob.check()["components"][0]["closed"])

# Labelled surfaces between regions of space, with their intersection curves.
saucer = skelform.load_scene("examples/nonmanifold/saucer-and-square.toml").mesh()
print(saucer, "region pairs:", sorted({(int(a), int(b)) for a, b in saucer.labels}))
if len(sys.argv) > 1:
    saucer.write(sys.argv[1])
