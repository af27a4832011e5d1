#!/usr/bin/env python3
"""Load skelform's outputs with the libraries other people use, and check what they see.

Usage: check_readers.py DIR SKELFORM

DIR holds meshes written by `skelform mesh` (as tests/interop/run.sh makes them); SKELFORM
is the binary, whose `check --json` gives the counts each library must find. For every
file, each of trimesh, meshio and pymeshlab (where it reads the format) must load it and
see the same vertices and faces; labelled PLY faces must keep region_a/region_b and carry
the palette colours; curve files must give their segments; closed examples must be
watertight for trimesh. Exit status 0 when all is as expected, 1 otherwise.

Known limits of the libraries, checked as such rather than skipped silently:
- meshio's binary PLY reader reads a face element as if `vertex_indices` were its only
  property, so labelled binary PLY (faces with region_a/region_b/colours) fails there; the
  ASCII form (`--ascii`) of the same layout reads, labels and colours included.
- meshio reads no glTF, and its PLY reader knows only `vertex` and `face` elements, so it
  cannot read an `OUT.curves.ply` (nor the `--ply-curves inline` layout).
- pymeshlab's glTF reader fails on line primitives: only `--no-curves` glb files go to it.
- trimesh splits OBJ and glTF by material, each part with its own vertices: for those the
  face count is compared, not the vertex count.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np

# The palette of crates/skelform-mesh/src/palette.rs, by rank of the sorted labels.
PALETTE = [
    (84, 140, 204), (230, 142, 62), (104, 176, 96), (206, 86, 86), (152, 118, 196),
    (72, 178, 178), (214, 182, 72), (210, 124, 172), (140, 110, 82), (150, 150, 150),
]

failures = []
checks = 0


def expect(cond, what):
    global checks
    checks += 1
    if not cond:
        failures.append(what)
        print(f"  FAIL {what}")


def reference(skelform, path):
    out = subprocess.run([skelform, "check", str(path), "--json"], capture_output=True, check=True)
    return json.loads(out.stdout)


def closed(ref):
    return ref["boundary_edges"] == 0 and ref["non_manifold_edges"] == 0


def ply_mesh(path, ref, trimesh, meshio, pymeshlab):
    labelled = bool(ref["labels"])
    # trimesh: counts, labels kept as face attributes, colours per face, watertight.
    m = trimesh.load(path, process=False)
    expect(isinstance(m, trimesh.Trimesh), f"{path.name}: trimesh gives a Trimesh ({type(m).__name__})")
    expect(len(m.vertices) == ref["vertices"], f"{path.name}: trimesh vertices {len(m.vertices)} == {ref['vertices']}")
    expect(len(m.faces) == ref["faces"], f"{path.name}: trimesh faces {len(m.faces)} == {ref['faces']}")
    if labelled:
        face = m.metadata["_ply_raw"]["face"]["data"]
        a = np.asarray(face["region_a"]).ravel()
        b = np.asarray(face["region_b"]).ravel()
        pairs = sorted({(int(x), int(y)) for x, y in zip(a, b)})
        want = sorted(tuple(l["label"]) for l in ref["labels"])
        expect(pairs == want, f"{path.name}: trimesh labels {pairs} == {want}")
        expect(m.visual.kind == "face", f"{path.name}: trimesh sees face colours ({m.visual.kind})")
        rank = {p: k for k, p in enumerate(pairs)}
        colours = np.asarray(m.visual.face_colors)[:, :3]
        want_c = np.array([PALETTE[rank[(int(x), int(y))] % len(PALETTE)] for x, y in zip(a, b)])
        expect(np.array_equal(colours, want_c), f"{path.name}: face colours are the palette's")
    if closed(ref):
        expect(m.is_watertight, f"{path.name}: trimesh finds it watertight")
    # meshio: points, triangles, labels as cell data. Its binary PLY reader reads a face
    # element as if `vertex_indices` were its only property (column by column), so a binary
    # file with labels fails there; the ASCII form of the same layout reads.
    ascii = path.read_bytes()[:40].find(b"format ascii") >= 0
    if labelled and not ascii:
        try:
            meshio.read(path)
            expect(False, f"{path.name}: meshio read binary faces with labels (update the docs)")
        except BaseException:
            pass
        mm = None
    else:
        mm = meshio.read(path)
    if mm is None:
        pass
    else:
        check_meshio(path, mm, ref, labelled)
    # pymeshlab: counts and face colours.
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    c = ms.current_mesh()
    expect(c.vertex_number() == ref["vertices"], f"{path.name}: pymeshlab vertices {c.vertex_number()} == {ref['vertices']}")
    expect(c.face_number() == ref["faces"], f"{path.name}: pymeshlab faces {c.face_number()} == {ref['faces']}")
    if labelled:
        expect(c.has_face_color(), f"{path.name}: pymeshlab sees face colours")


def check_meshio(path, mm, ref, labelled):
    tri = sum(len(c.data) for c in mm.cells if c.type == "triangle")
    expect(len(mm.points) == ref["vertices"], f"{path.name}: meshio points {len(mm.points)} == {ref['vertices']}")
    expect(tri == ref["faces"], f"{path.name}: meshio triangles {tri} == {ref['faces']}")
    if labelled:
        expect({"region_a", "region_b", "red"} <= set(mm.cell_data), f"{path.name}: meshio keeps labels and colours ({sorted(mm.cell_data)})")


def ply_curves(path, ref, trimesh, meshio, pymeshlab):
    segments = ref["curves"]
    p = trimesh.load(path, process=False)
    expect(type(p).__name__ == "Path3D", f"{path.name}: trimesh gives a Path3D ({type(p).__name__})")
    edges = sum(len(e.points) - 1 for e in p.entities)
    expect(edges == segments, f"{path.name}: trimesh path segments {edges} == {segments}")
    ms = pymeshlab.MeshSet()
    ms.load_new_mesh(str(path))
    expect(ms.current_mesh().edge_number() == segments, f"{path.name}: pymeshlab edges {ms.current_mesh().edge_number()} == {segments}")
    # meshio refuses it (and calls sys.exit after printing why, hence BaseException).
    try:
        meshio.read(path)
        expect(False, f"{path.name}: meshio was expected to refuse an edge element (it read it: update the docs)")
    except BaseException:
        pass


def colour(m):
    """The colour trimesh gives a part: its material's (glTF, OBJ) or its own."""
    material = getattr(m.visual, "material", None)
    c = material.main_color if material is not None else m.visual.main_color
    return tuple(int(v) for v in np.asarray(c)[:3])


def other_format(path, ref, trimesh, meshio, pymeshlab):
    ext = path.suffix.lower()
    scene = trimesh.load(path, process=False)
    if isinstance(scene, trimesh.Scene):
        meshes = [g for g in scene.dump() if isinstance(g, trimesh.Trimesh)]
        paths = [g for g in scene.dump() if not isinstance(g, trimesh.Trimesh)]
    else:
        meshes, paths = [scene], []
    faces = sum(len(m.faces) for m in meshes)
    expect(faces == ref["faces"], f"{path.name}: trimesh faces {faces} == {ref['faces']}")
    if ext == ".stl" or (ext == ".glb" and not ref["labels"]) or (ext == ".obj" and not ref["labels"]):
        if len(meshes) == 1 and ext != ".stl":
            expect(len(meshes[0].vertices) == ref["vertices"], f"{path.name}: trimesh vertices {len(meshes[0].vertices)} == {ref['vertices']}")
    if ref["labels"] and ext in (".glb", ".obj"):
        expect(len(meshes) == len(ref["labels"]), f"{path.name}: trimesh parts {len(meshes)} == {len(ref['labels'])} region pairs")
        colours = sorted({colour(m) for m in meshes})
        expect(len(colours) == len(ref["labels"]), f"{path.name}: one colour per region pair ({colours})")
    if ext == ".glb" and ref["curves"]:
        expect(len(paths) > 0, f"{path.name}: trimesh finds the curves as paths")
    if closed(ref) and len(meshes) == 1:
        whole = meshes[0] if ext != ".stl" else meshes[0].copy()
        if ext == ".stl":
            whole.merge_vertices()
        expect(whole.is_watertight, f"{path.name}: trimesh finds it watertight")
    if ext in (".obj", ".stl"):
        mm = meshio.read(path)
        tri = sum(len(c.data) for c in mm.cells if c.type == "triangle")
        expect(tri == ref["faces"], f"{path.name}: meshio triangles {tri} == {ref['faces']}")
    if ext != ".glb" or ref["curves"] == 0:
        ms = pymeshlab.MeshSet()
        ms.load_new_mesh(str(path))
        c = ms.current_mesh()
        total = sum(ms.mesh(i).face_number() for i in range(ms.mesh_number()))
        expect(total == ref["faces"], f"{path.name}: pymeshlab faces {total} == {ref['faces']}")
        if ext == ".obj" and ref["labels"]:
            expect(c.has_face_color() or c.has_wedge_tex_coord() or c.has_vertex_color(),
                   f"{path.name}: pymeshlab takes the .mtl colours")


def written_by_trimesh(folder, skelform, trimesh):
    """The other way round: skelform reads the .glb trimesh writes (nodes with transforms)."""
    box = trimesh.creation.box(extents=(1.0, 2.0, 3.0))
    scene = trimesh.Scene()
    move = trimesh.transformations.translation_matrix((10.0, 0.0, 0.0))
    turn = trimesh.transformations.rotation_matrix(np.pi / 2, (0.0, 0.0, 1.0))
    scene.add_geometry(box, node_name="box", transform=move @ turn)
    path = folder / "from-trimesh.glb"
    path.write_bytes(scene.export(file_type="glb"))
    print(path.name)
    ref = reference(skelform, path)
    expect(ref["faces"] == 12, f"{path.name}: skelform reads 12 faces ({ref['faces']})")
    lo, hi = ref["bounds"]["min"], ref["bounds"]["max"]
    # Turned a quarter about z, the box's 2-long side lies along x, centred at x = 10.
    want_lo, want_hi = (9.0, -0.5, -1.5), (11.0, 0.5, 1.5)
    expect(all(abs(a - b) < 1e-5 for a, b in zip(lo + hi, want_lo + want_hi)),
           f"{path.name}: skelform applies the node transform (bounds {lo} {hi})")
    expect(closed(ref) and ref["components"][0].get("outward") is True,
           f"{path.name}: closed and outward after the transform")
    path.unlink()


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    folder, skelform = Path(sys.argv[1]), sys.argv[2]
    import meshio
    import pymeshlab
    import trimesh

    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in (".ply", ".obj", ".stl", ".glb"))
    for path in files:
        print(path.name)
        if path.name.endswith(".curves.ply"):
            mesh = path.with_name(path.name[: -len(".curves.ply")] + ".ply")
            ply_curves(path, reference(skelform, mesh), trimesh, meshio, pymeshlab)
        elif path.suffix.lower() == ".ply":
            ply_mesh(path, reference(skelform, path), trimesh, meshio, pymeshlab)
        else:
            other_format(path, reference(skelform, path), trimesh, meshio, pymeshlab)
    written_by_trimesh(folder, skelform, trimesh)
    print(f"{len(files)} files, {checks} checks, {len(failures)} failed")
    sys.exit(1 if failures or not files else 0)


if __name__ == "__main__":
    main()
