"""Writes, with nibabel, NIfTI variants otoatlas must read: big-endian NIfTI-1 with scaling,
an .hdr/.img pair (float32) and a gzipped NIfTI-2; prints what nibabel reads back from each
(dims, affine in RAS, sum of values and three voxels) as JSON on stdout.

usage: write_nifti_variants.py OUT_DIR
"""
import json
import sys

import nibabel as nib
import numpy as np

out = sys.argv[1]
values = np.arange(6 * 5 * 4).reshape(6, 5, 4) * 7 % 23 - 4
affine = np.array(
    [[0.0, 0.3, 0.0, 1.5], [-0.2, 0.0, 0.0, 2.0], [0.0, 0.0, 0.25, -3.0], [0, 0, 0, 1]]
)
be = nib.Nifti1Image(values.astype(">i2"), affine)
be.set_data_dtype(">i2")
be.header.set_slope_inter(2.0, -5.0)
files = {
    "big_endian.nii": be,
    "pair.hdr": nib.Nifti1Pair(values.astype("<f4"), affine),
    "nifti2.nii.gz": nib.Nifti2Image(values.astype("<i2"), affine),
}
report = {}
for name, img in files.items():
    nib.save(img, f"{out}/{name}")
    back = nib.load(f"{out}/{name}")
    data = back.get_fdata()
    report[name] = {
        "dims": list(data.shape),
        "affine_ras": back.affine.tolist(),
        "sum": float(data.sum()),
        "voxels": [[i, j, k, float(data[i, j, k])] for i, j, k in [(0, 0, 0), (5, 4, 3), (2, 3, 1)]],
    }
print(json.dumps(report))
