"""Independent reader check: pydicom and nibabel read a DICOM series and a NIfTI file written by
otoatlas, and must find the geometry and voxels the Rust side says it wrote.

usage: check_volume.py EXPECTED.json DICOM_DIR NIFTI_FILE
EXPECTED.json: {"dims": [nx, ny, nz], "spacing": [...], "origin": [...] (LPS),
                "direction": [9, row-major, columns = voxel axes in LPS], "sum": float,
                "probes": [[i, j, k, value], ...]}
"""
import json
import pathlib
import sys

import nibabel
import numpy as np
import pydicom


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def close(a, b, tol, what):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape or not np.allclose(a, b, atol=tol, rtol=0):
        fail(f"{what}: {a.tolist()} != {b.tolist()}")


def from_dicom(folder):
    slices = [pydicom.dcmread(p) for p in pathlib.Path(folder).iterdir() if p.is_file()]
    iop = np.array(slices[0].ImageOrientationPatient, float)
    row, col = iop[:3], iop[3:]
    normal = np.cross(row, col)
    slices.sort(key=lambda d: float(np.dot(normal, np.array(d.ImagePositionPatient, float))))
    pos = np.array([d.ImagePositionPatient for d in slices], float)
    span = pos[-1] - pos[0]
    dz = np.linalg.norm(span) / (len(slices) - 1)
    ps = [float(v) for v in slices[0].PixelSpacing]  # row spacing, column spacing
    vol = np.stack([d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept) for d in slices])
    # pydicom arrays are [k][row=j][col=i]
    direction = np.column_stack([row, col, span / np.linalg.norm(span)])
    return dict(dims=[vol.shape[2], vol.shape[1], vol.shape[0]], spacing=[ps[1], ps[0], dz],
                origin=pos[0], direction=direction, data=np.transpose(vol, (2, 1, 0)))


def from_nifti(path):
    img = nibabel.load(path)
    aff = np.diag([-1.0, -1.0, 1.0, 1.0]) @ img.affine  # RAS -> LPS
    m = aff[:3, :3]
    spacing = np.linalg.norm(m, axis=0)
    data = np.asarray(img.get_fdata())
    return dict(dims=list(data.shape), spacing=spacing, origin=aff[:3, 3],
                direction=m / spacing, data=data)


def main():
    expected = json.loads(pathlib.Path(sys.argv[1]).read_text())
    for name, got in (("pydicom", from_dicom(sys.argv[2])), ("nibabel", from_nifti(sys.argv[3]))):
        if list(got["dims"]) != expected["dims"]:
            fail(f"{name} dims {got['dims']} != {expected['dims']}")
        close(got["spacing"], expected["spacing"], 1e-5, f"{name} spacing")
        close(got["origin"], expected["origin"], 1e-4, f"{name} origin")
        close(np.asarray(got["direction"]).reshape(-1), expected["direction"], 1e-5, f"{name} direction")
        total = float(got["data"].sum())
        if abs(total - expected["sum"]) > 1e-6 * max(1.0, abs(expected["sum"])) + 1e-3:
            fail(f"{name} voxel sum {total} != {expected['sum']}")
        for i, j, k, v in expected["probes"]:
            i, j, k = int(i), int(j), int(k)
            if abs(got["data"][i, j, k] - v) > 1e-3:
                fail(f"{name} voxel ({i},{j},{k}) = {got['data'][i, j, k]} != {v}")
        print(f"{name}: ok")


main()
