"""Writes a copy of a phantom's image with its ossicles removed: every voxel within two voxels
of an ossicle label (1-3 in labels.nii.gz) becomes air with noise, so no chain is left to find.

usage: remove_ossicles.py IMAGE LABELS OUT
"""
import sys

import nibabel as nib
import numpy as np

image = nib.load(sys.argv[1])
voxels = np.asarray(image.dataobj).astype(np.float32)
labels = np.asarray(nib.load(sys.argv[2]).dataobj)
gone = np.isin(labels, [1, 2, 3])
for _ in range(2):
    grown = gone.copy()
    for axis in range(3):
        for shift in (-1, 1):
            grown |= np.roll(gone, shift, axis=axis)
    gone = grown
voxels[gone] = -1000 + np.random.default_rng(1).normal(0, 40, gone.sum())
nib.save(nib.Nifti1Image(voxels, image.affine, image.header), sys.argv[3])
print(int(gone.sum()))
