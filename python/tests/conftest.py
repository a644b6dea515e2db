# SPDX-License-Identifier: Apache-2.0
"""Shared helpers of the psq Python tests: meshes generated with numpy (no data files)."""

import os
import shutil

import numpy as np
import pytest


def grid_mesh(n: int = 20, m: int = None, dtype=np.float32, wave: float = 0.3):
    """A height field of n x m vertices in row order: 2 (n-1)(m-1) triangles, one border loop."""
    m = n if m is None else m
    y, x = np.meshgrid(np.arange(m, dtype=np.float64), np.arange(n, dtype=np.float64), indexing="ij")
    z = np.sin(x * wave) * np.cos(y * wave)
    positions = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1).astype(dtype)
    i = (np.arange(m - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    faces = np.concatenate([np.stack([i, i + 1, i + n], 1), np.stack([i + 1, i + n + 1, i + n], 1)])
    order = np.argsort(np.minimum.reduce([faces[:, 0], faces[:, 1], faces[:, 2]]), kind="stable")
    return positions, faces[order].astype(np.uint32)


def canonical(positions, faces):
    """The mesh's triangles as sorted rows of corner coordinates, independent of vertex and triangle order
    and of each triangle's first corner (orientation kept: corners rotated to start at the smallest)."""
    tri = positions[faces.astype(np.int64)].astype(np.float64)  # m x 3 x 3
    keys = [tuple(map(tuple, t)) for t in tri]
    out = []
    for k in keys:
        r = min(range(3), key=lambda j: k[j])
        out.append(k[r:] + k[:r])
    return sorted(out)


@pytest.fixture
def psq_binary():
    """The psq tool of the build tree (set by ctest), or None."""
    path = os.environ.get("PSQ_BINARY") or shutil.which("psq")
    return path if path and os.path.exists(path) else None
