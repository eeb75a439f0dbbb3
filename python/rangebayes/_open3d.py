"""Open3D interop (open3d is optional: imported only when these functions are called)."""

import numpy as np

from ._rangebayes import Mesh, NoisyMesh


def _o3d():
    try:
        import open3d
    except ImportError as e:  # pragma: no cover - depends on the machine
        raise ImportError("to_open3d/from_open3d need open3d (Debian: apt-get install python3-open3d)") from e
    return open3d


def to_open3d(mesh):
    """An open3d.geometry.TriangleMesh with the vertices, faces and (when present) vertex normals of a Mesh,
    NoisyMesh or DecimatedMesh (copies: Open3D owns its own storage)."""
    if hasattr(mesh, "corner_normals") and hasattr(mesh, "polygons"):
        mesh = mesh.mesh
    if not isinstance(mesh, (Mesh, NoisyMesh)):
        raise TypeError(f"to_open3d: expected a Mesh, NoisyMesh or DecimatedMesh, got {type(mesh)}")
    F = np.asarray(mesh.F)
    n = mesh.V.shape[0]
    if F.size and (F.min() < 0 or F.max() >= n):
        # Open3D does not check its triangles: a bad index crashes the interpreter in its first computation.
        bad = int(np.argmax((F < 0).any(axis=1) | (F >= n).any(axis=1)))
        raise ValueError(f"to_open3d: face {bad} uses vertex {F[bad].tolist()} but there are {n} vertices")
    o3d = _o3d()
    out = o3d.geometry.TriangleMesh()
    out.vertices = o3d.utility.Vector3dVector(np.ascontiguousarray(mesh.V, dtype=np.float64))
    out.triangles = o3d.utility.Vector3iVector(np.ascontiguousarray(mesh.F, dtype=np.int32))
    if mesh.N.shape[0] == mesh.V.shape[0] and mesh.V.shape[0] > 0:
        out.vertex_normals = o3d.utility.Vector3dVector(np.ascontiguousarray(mesh.N, dtype=np.float64))
    return out


def from_open3d(o3d_mesh):
    """A rangebayes.Mesh from an open3d.geometry.TriangleMesh (copies vertices, triangles, vertex normals)."""
    if not all(hasattr(o3d_mesh, a) for a in ("vertices", "triangles", "has_vertex_normals")):
        raise TypeError(f"from_open3d: expected an open3d.geometry.TriangleMesh, got {type(o3d_mesh)}")
    V = np.asarray(o3d_mesh.vertices)
    F = np.asarray(o3d_mesh.triangles)
    N = np.asarray(o3d_mesh.vertex_normals) if o3d_mesh.has_vertex_normals() else None
    return Mesh(V, F, N)
