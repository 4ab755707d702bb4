#!/usr/bin/env python3
"""Independent check of a patient package's meshes with meshio (the reader ParaView-side tools
and many SOFA users' scripts rely on).

usage: check_package.py PACKAGE_DIR

Reads mesh.msh (Gmsh 2.2) and mesh.vtu and checks against manifest.json and atlas.json (read
with the standard library): the point count; the tetra and triangle cell counts; the Gmsh
physical names (one per atlas region, by its name);
physical and geometrical tags of every cell equal its region label in mesh.vtu, and the set of
labels per cell type equals atlas.json's volumetric / membrane regions; the points of both files
agree; every tetrahedron has a positive volume. Prints "ok" or "FAIL: ..." and exits 1.
"""
import json
import pathlib
import sys

import meshio
import numpy as np


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def by_type(mesh, key):
    out = {}
    for block, data in zip(mesh.cells, mesh.cell_data[key]):
        out.setdefault(block.type, []).append(np.asarray(data).astype(int).reshape(-1))
    return {k: np.concatenate(v) for k, v in out.items()}


def cells(mesh):
    out = {}
    for block in mesh.cells:
        out.setdefault(block.type, []).append(block.data)
    return {k: np.concatenate(v) for k, v in out.items()}


def main():
    pkg = pathlib.Path(sys.argv[1])
    manifest = json.loads((pkg / "manifest.json").read_text())
    atlas = json.loads((pkg / "atlas.json").read_text())
    counts = manifest["mesh"]
    msh = meshio.read(pkg / "mesh.msh")
    vtu = meshio.read(pkg / "mesh.vtu")
    for name, m in [("mesh.msh", msh), ("mesh.vtu", vtu)]:
        c = {k: len(v) for k, v in cells(m).items()}
        want = {"tetra": counts["tetrahedra"], "triangle": counts["triangles"]}
        if len(m.points) != counts["nodes"] or c != want:
            fail(f"{name}: {len(m.points)} points, cells {c}; manifest {counts}")
    if not np.array_equal(msh.points, vtu.points):
        fail("mesh.msh and mesh.vtu points differ")
    for k, v in cells(msh).items():
        if not np.array_equal(v, cells(vtu)[k]):
            fail(f"mesh.msh and mesh.vtu {k} connectivity differs")
    physical = by_type(msh, "gmsh:physical")
    geometrical = by_type(msh, "gmsh:geometrical")
    region = by_type(vtu, "region")
    membrane = {r["label"] for r in atlas["regions"] if "thickness_mm" in r}
    volumetric = {r["label"] for r in atlas["regions"] if "thickness_mm" not in r}
    for kind, labels in [("tetra", volumetric), ("triangle", membrane)]:
        if not np.array_equal(physical[kind], region[kind]):
            fail(f"{kind}: gmsh:physical differs from mesh.vtu's region")
        if not np.array_equal(geometrical[kind], region[kind]):
            fail(f"{kind}: gmsh:geometrical differs from mesh.vtu's region")
        if set(np.unique(physical[kind]).tolist()) != labels:
            fail(f"{kind}: physical tags {np.unique(physical[kind])}, atlas regions {labels}")
    # $PhysicalNames: every region by its atlas name, with its label and dimension
    for r in atlas["regions"]:
        dim = 2 if r["label"] in membrane else 3
        got = msh.field_data.get(r["name"])
        if got is None or [int(got[0]), int(got[1])] != [r["label"], dim]:
            fail(f"mesh.msh physical name {r['name']!r}: {got}, expected [{r['label']}, {dim}]")
    p = msh.points[cells(msh)["tetra"]]
    vol = np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0])) / 6
    if not np.all(vol > 0):
        fail(f"{int(np.sum(vol <= 0))} tetrahedra with a volume <= 0")
    print("ok")


if __name__ == "__main__":
    main()
