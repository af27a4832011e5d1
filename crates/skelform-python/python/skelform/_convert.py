"""Meshes to the objects of other libraries (imported only when asked for)."""

import numpy as np


def to_trimesh(mesh):
    """A ``trimesh.Trimesh`` of the mesh, its vertices and faces as they are (no merging)."""
    import trimesh

    normals = mesh.normals
    return trimesh.Trimesh(
        vertices=mesh.vertices,
        faces=mesh.faces,
        vertex_normals=normals if len(normals) else None,
        process=False,
    )


def to_pyvista(mesh):
    """A ``pyvista.PolyData`` of the mesh, with normals and region labels as data."""
    import pyvista

    faces = mesh.faces
    cells = np.hstack([np.full((len(faces), 1), 3, dtype=np.int64), faces]).ravel()
    poly = pyvista.PolyData(mesh.vertices, cells)
    normals = mesh.normals
    if len(normals):
        poly.point_data["Normals"] = normals
    labels = mesh.labels
    if len(labels):
        poly.cell_data["labels"] = labels
    return poly
