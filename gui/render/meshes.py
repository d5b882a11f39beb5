"""Unit meshes for instanced drawing: a capped cylinder along +Z (bones) and an icosphere (joints).

Each returns interleaved float32 (N, 6) rows ``[x, y, z, nx, ny, nz]`` as separate triangles."""
from __future__ import annotations

import numpy as np


def unit_cylinder(sides: int = 10) -> np.ndarray:
    """Radius-1 cylinder from z=0 to z=1 (side walls only: caps are hidden inside the joint spheres)."""
    ang = np.linspace(0.0, 2 * np.pi, sides + 1)
    c, s = np.cos(ang), np.sin(ang)
    i = np.arange(sides)
    # per side: two triangles (i,0) (i+1,0) (i+1,1) / (i,0) (i+1,1) (i,1)
    ring = lambda k, z: np.c_[c[k], s[k], np.full(len(k), z), c[k], s[k], np.zeros(len(k))]  # noqa: E731
    tris = np.stack([ring(i, 0), ring(i + 1, 0), ring(i + 1, 1), ring(i, 0), ring(i + 1, 1), ring(i, 1)], axis=1)
    return tris.reshape(-1, 6).astype("f4")


def unit_sphere(subdivisions: int = 1) -> np.ndarray:
    """Radius-1 icosphere; normals equal positions."""
    t = (1.0 + 5 ** 0.5) / 2.0
    verts = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t],
                      [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    faces = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
                      [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
                      [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    tris = verts[faces]  # (F, 3, 3)
    for _ in range(subdivisions):
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
        tris = np.concatenate([np.stack(x, 1) for x in ([a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca])])
    p = tris.reshape(-1, 3)
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    return np.c_[p, p].astype("f4")
