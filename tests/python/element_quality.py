#!/usr/bin/env python3
"""Independent reading of a package's element quality with meshio and numpy.

usage: element_quality.py PACKAGE_DIR ATLAS_MESH_VTU

Reads PACKAGE_DIR/mesh.msh (Gmsh 2.2), the atlas's mesh.vtu and the landmark fit's scale from
manifest.json, and prints as JSON the smallest shape quality (volume over the regular
tetrahedron's with the same RMS edge length, V / (l_rms^3 / (6 sqrt 2))) and the smallest ratio
of a tetrahedron's volume to |its atlas volume| * scale^3, each with its 0-based tetrahedron.
"""
import json
import pathlib
import sys

import meshio
import numpy as np


def tetra(mesh):
    return np.concatenate([b.data for b in mesh.cells if b.type == "tetra"])


def volumes(points, tets):
    p = points[tets]
    u, v, w = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
    return np.einsum("ij,ij->i", u, np.cross(v, w)) / 6.0


def main():
    pkg = pathlib.Path(sys.argv[1])
    scale = json.loads((pkg / "manifest.json").read_text())["atlas_to_patient"]["scale"]
    msh = meshio.read(pkg / "mesh.msh")
    atlas = meshio.read(sys.argv[2])
    tets = tetra(msh)
    p = msh.points[tets]
    edges = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    mean_square = sum(((p[:, a] - p[:, b]) ** 2).sum(axis=1) for a, b in edges) / 6.0
    quality = volumes(msh.points, tets) / (mean_square**1.5 / (6.0 * np.sqrt(2.0)))
    ratio = volumes(msh.points, tets) / (np.abs(volumes(atlas.points, tetra(atlas))) * scale**3)
    q, r = int(np.argmin(quality)), int(np.argmin(ratio))
    print(json.dumps({
        "min_shape_quality": float(quality[q]),
        "min_shape_quality_tetrahedron": q,
        "min_volume_ratio": float(ratio[r]),
        "min_volume_ratio_tetrahedron": r,
    }))


if __name__ == "__main__":
    main()
