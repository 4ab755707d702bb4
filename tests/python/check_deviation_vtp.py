#!/usr/bin/env python3
"""Independent reading of a run's deviation maps: each registered/deviation/NAME.vtp by VTK's
own XML PolyData reader, against NAME.ply beside it read by meshio.

usage: check_deviation_vtp.py DEVIATION_DIR

For every NAME.ply asserts that NAME.vtp has the point data array `deviation_mm` (the active
scalars), the same points, the same triangles and the same values as the PLY's `quality`
(to the PLY's precision); prints {"maps": N, "points": total}.
"""
import json
import pathlib
import sys

import meshio
import numpy as np
import vtk
from vtk.util.numpy_support import vtk_to_numpy


def main():
    folder = pathlib.Path(sys.argv[1])
    plys = sorted(folder.glob("*.ply"))
    assert plys, f"no deviation map in {folder}"
    total = 0
    for ply_path in plys:
        vtp_path = ply_path.with_suffix(".vtp")
        reader = vtk.vtkXMLPolyDataReader()
        reader.SetFileName(str(vtp_path))
        reader.Update()
        poly = reader.GetOutput()
        assert poly.GetNumberOfPoints() > 0, f"{vtp_path}: VTK read no points"
        scalars = poly.GetPointData().GetScalars()
        assert scalars is not None, f"{vtp_path}: no active point scalars"
        assert scalars.GetName() == "deviation_mm", f"{vtp_path}: {scalars.GetName()}"
        values = vtk_to_numpy(scalars)
        points = vtk_to_numpy(poly.GetPoints().GetData())
        polys = vtk_to_numpy(poly.GetPolys().GetConnectivityArray()).reshape(-1, 3)
        assert poly.GetPolys().GetNumberOfCells() == len(polys)

        ply = meshio.read(ply_path)
        triangles = np.concatenate([c.data for c in ply.cells if c.type == "triangle"])
        quality = np.asarray(ply.point_data["quality"], dtype=float)
        assert len(values) == len(ply.points) == len(quality), (
            f"{vtp_path}: {len(values)} values, PLY {len(ply.points)} points"
        )
        assert np.array_equal(polys, triangles), f"{vtp_path}: triangles differ"
        precision = np.finfo(np.float32).eps * 4
        assert np.allclose(points, ply.points, rtol=precision, atol=1e-6), vtp_path
        assert np.allclose(values, quality, rtol=precision, atol=1e-6), vtp_path
        total += len(values)
    print(json.dumps({"maps": len(plys), "points": int(total)}))


if __name__ == "__main__":
    main()
