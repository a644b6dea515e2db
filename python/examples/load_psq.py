#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Loads a .psq (or any mesh psq reads) into trimesh or Open3D when one is installed,
else prints the numpy arrays.

    PYTHONPATH=build/python python3 python/examples/load_psq.py mesh.psq [--stream]

With --stream the file is read chunk by chunk (psq.open) and the processing
sequence is summarized instead: how many triangles of each op, and the
longest processing boundary the decoder kept.
"""

import sys

import numpy as np

import psq


def stream_summary(path: str) -> None:
    ops = np.zeros(len(psq.OPS), dtype=np.int64)
    with psq.open(path) as stream:
        print("header:", stream.header)
        for chunk in stream:
            ops += np.bincount(chunk.ops, minlength=len(psq.OPS))
        stats = stream.stats
    print("ops:", dict(zip(psq.OPS, ops.tolist())))
    print(f"{stats['triangles']} triangles; at most {stats['max_active_vertices']} active vertices and "
          f"{stats['max_open_edges']} open edges")


def main(argv) -> int:
    if len(argv) < 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    path = argv[1]
    try:
        if "--stream" in argv[2:]:
            stream_summary(path)
            return 0
        mesh = psq.read(path)
    except psq.Error as e:
        print(f"load_psq: error: {e}", file=sys.stderr)
        return 1
    print(mesh)
    try:
        import trimesh
        tm = trimesh.Trimesh(vertices=mesh.positions, faces=mesh.faces, process=False)
        print("trimesh:", tm, "area", tm.area, "watertight", tm.is_watertight)
        return 0
    except ImportError:
        pass
    try:
        import open3d as o3d
        om = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(mesh.positions.astype(np.float64)),
                                       o3d.utility.Vector3iVector(mesh.faces.astype(np.int32)))
        print("Open3D:", om, "area", om.get_surface_area())
        return 0
    except ImportError:
        pass
    np.set_printoptions(threshold=12, edgeitems=3)
    print("positions", mesh.positions.dtype, mesh.positions.shape)
    print(mesh.positions)
    print("faces", mesh.faces.dtype, mesh.faces.shape)
    print(mesh.faces)
    for kind, props in (("vertex", mesh.vertex_properties), ("face", mesh.face_properties)):
        for name, values in props.items():
            print(f"{kind} property {name}:", values)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
