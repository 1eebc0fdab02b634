"""Mesh input/output: OBJ and PLY keeping vertex order, faces and UVs; atomic writes.

Only NumPy is imported here (no numba), so the CLI may import this module inside a command.
"""
from vfit_engine.io.atomic import atomic_write
from vfit_engine.io.mesh import read_mesh, write_mesh
from vfit_engine.io.meshdata import MAX_VERTS, MeshData, mesh_from_faces

__all__ = ["MAX_VERTS", "MeshData", "atomic_write", "mesh_from_faces", "read_mesh", "write_mesh"]
