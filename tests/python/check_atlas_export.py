#!/usr/bin/env python3
"""Independent check of `otoatlas atlas export` with trimesh, meshio and the standard library.

usage: check_atlas_export.py OUT_DIR EXPECTED.json
EXPECTED.json (from `otoatlas atlas info --json`, arranged by the Rust test):
  {"tetrahedra": n, "triangles": n,
   "bones": {"malleus": volume_mm3, "incus": ..., "stapes": ...},
   "bone_masses": {"malleus": [mass_mg, [region labels]], "incus": ..., "stapes": ...},
   "eardrum_area": mm2,
   "regions": {"<label>": [youngs_modulus_pa, density_kg_m3, poisson_ratio, thickness_mm]},
   "landmarks": {"umbo": [x, y, z], "incudomalleolar": [...], "incudostapedial": [...]}}

Checks: each bone PLY is watertight, consistently wound, outward (positive volume equal to
the atlas's bone volume) and one piece; the eardrum PLY is an open disc (one piece, Euler
characteristic 1, one boundary loop) with the atlas's area; volume.vtu has exactly the atlas's
tetra and triangle cells, and its region, Young's modulus, density, Poisson's ratio and
thickness per cell match the atlas's regions, and each bone's mass (its tetrahedra's volumes
times their density, summed over its regions' cells) is the one `atlas info` reports; landmarks.json and landmarks.fcsv (LPS) hold the
atlas's landmarks. Prints "ok" or "FAIL: ..." and exits 1 on failure.
"""
import json
import pathlib
import sys

import meshio
import numpy as np
import trimesh


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def main():
    out = pathlib.Path(sys.argv[1])
    expected = json.loads(pathlib.Path(sys.argv[2]).read_text())
    for bone, volume in expected["bones"].items():
        m = trimesh.load(out / "surfaces" / f"{bone}.ply", process=False, force="mesh")
        if not m.is_watertight or not m.is_winding_consistent:
            fail(f"{bone}.ply: watertight {m.is_watertight}, consistent {m.is_winding_consistent}")
        if not abs(m.volume - volume) <= 1e-6 * volume:
            fail(f"{bone}.ply: volume {m.volume} (outward: positive), atlas {volume}")
        # every ossicle is one closed piece
        pieces = m.split(only_watertight=False)
        if len(pieces) != 1:
            fail(f"{bone}.ply: {len(pieces)} pieces, expected one")
    drum = trimesh.load(out / "surfaces" / "eardrum.ply", process=False, force="mesh")
    edges = drum.edges_sorted
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    border = unique[counts == 1]
    border_vertices = np.unique(border)
    if drum.is_watertight or drum.euler_number != 1 or len(drum.split(only_watertight=False)) != 1:
        fail(f"eardrum.ply: watertight {drum.is_watertight}, euler {drum.euler_number}")
    if len(border) != len(border_vertices) or np.any(counts > 2):
        fail("eardrum.ply: the border is not one simple loop of manifold edges")
    if not abs(drum.area - expected["eardrum_area"]) <= 1e-6 * expected["eardrum_area"]:
        fail(f"eardrum.ply: area {drum.area}, atlas {expected['eardrum_area']}")

    vol = meshio.read(out / "volume.vtu")
    cells = {c.type: len(c.data) for c in vol.cells}
    if cells != {"tetra": expected["tetrahedra"], "triangle": expected["triangles"]}:
        fail(f"volume.vtu cells {cells}")
    data = vol.cell_data
    names = ["region", "youngs_modulus_pa", "density_kg_m3", "poisson_ratio", "thickness_mm"]
    for name in names:
        if name not in data:
            fail(f"volume.vtu: no cell array {name} (has {list(data)})")
    for block in range(len(vol.cells)):
        regions = np.asarray(data["region"][block]).astype(int)
        for label in np.unique(regions):
            want = expected["regions"][str(label)]
            for name, value in zip(names[1:], want):
                got = np.asarray(data[name][block])[regions == label]
                if not np.allclose(got, value, rtol=1e-12, atol=0):
                    fail(f"volume.vtu: {name} of region {label}: {np.unique(got)} != {value}")

    # each bone's mass from the cells alone: |det| / 6 per tetrahedron, times its density
    tetra = [i for i, c in enumerate(vol.cells) if c.type == "tetra"][0]
    corners = vol.points[vol.cells[tetra].data]
    volumes = np.abs(np.einsum(
        "ij,ij->i",
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
        corners[:, 3] - corners[:, 0],
    )) / 6.0
    labels = np.asarray(data["region"][tetra]).astype(int).ravel()
    density = np.asarray(data["density_kg_m3"][tetra]).ravel()
    for bone, (mass_mg, bone_labels) in expected["bone_masses"].items():
        inside = np.isin(labels, bone_labels)
        # mm^3 x kg/m^3 = 1e-9 kg = 1e-3 mg
        got = float(np.sum(volumes[inside] * density[inside])) * 1e-3
        if not abs(got - mass_mg) <= 1e-9 * mass_mg:
            fail(f"volume.vtu: {bone} weighs {got} mg from its cells, atlas info {mass_mg}")

    marks = json.loads((out / "landmarks.json").read_text())
    if marks.get("coordinate_system") != "LPS":
        fail(f"landmarks.json coordinate_system {marks.get('coordinate_system')}")
    fcsv = {}
    lines = (out / "landmarks.fcsv").read_text().splitlines()
    if "# CoordinateSystem = LPS" not in lines:
        fail("landmarks.fcsv is not in LPS")
    for line in lines:
        if line.startswith("#"):
            continue
        f = line.split(",")
        fcsv[f[11]] = [float(v) for v in f[1:4]]
    for name, point in expected["landmarks"].items():
        if not np.allclose(marks[name], point, atol=1e-9, rtol=0):
            fail(f"landmarks.json {name} {marks[name]} != {point}")
        if not np.allclose(fcsv[name], point, atol=1e-4, rtol=0):
            fail(f"landmarks.fcsv {name} {fcsv[name]} != {point}")
    print("ok")


if __name__ == "__main__":
    main()
