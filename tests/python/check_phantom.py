"""Independent check of a phantom case folder written by `otoatlas phantom`: pydicom and nibabel
must read the DICOM series, image.nii.gz and segmentation/labels.nii.gz with the geometry that
truth.json states and the same voxels, the DICOM must state the side, and the truth landmarks
must lie on the truth surfaces (PLY, parsed here with numpy) as the generator claims.

usage: check_phantom.py CASE_DIR
The IMJ and the umbo must be within 0.3 mm of their bones' surfaces; the ISJ within 0.65 mm of
the incus and the stapes, because the atlas's incudostapedial joint is a 0.95 mm thick disc
whose centre is the landmark (half of it, scaled by up to 1.1 and strained by the deformation).
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
    slices = [pydicom.dcmread(p) for p in sorted(pathlib.Path(folder).iterdir()) if p.is_file()]
    iop = np.array(slices[0].ImageOrientationPatient, float)
    row, col = iop[:3], iop[3:]
    normal = np.cross(row, col)
    in_file_order = [int(d.InstanceNumber) for d in slices]
    slices.sort(key=lambda d: float(np.dot(normal, np.array(d.ImagePositionPatient, float))))
    if in_file_order == sorted(in_file_order):
        fail("DICOM file names follow slice order")
    pos = np.array([d.ImagePositionPatient for d in slices], float)
    span = pos[-1] - pos[0]
    dz = np.linalg.norm(span) / (len(slices) - 1)
    ps = [float(v) for v in slices[0].PixelSpacing]
    vol = np.stack([d.pixel_array * float(d.RescaleSlope) + float(d.RescaleIntercept) for d in slices])
    direction = np.column_stack([row, col, span / np.linalg.norm(span)])
    first = slices[0]
    meta = dict(
        sop_class=str(first.SOPClassUID),
        # Laterality (0020,0060) must be absent beside Image Laterality (Type 2C)
        laterality=str(first.get("Laterality", "absent")),
        image_laterality=str(first.ImageLaterality),
        patient_name=str(first.PatientName),
        patient_id=str(first.PatientID),
        birth_date=str(first.PatientBirthDate),
        uids={str(d.SeriesInstanceUID) for d in slices}
        | {"study:" + str(d.StudyInstanceUID) for d in slices}
        | {"frame:" + str(d.FrameOfReferenceUID) for d in slices},
    )
    return dict(dims=[vol.shape[2], vol.shape[1], vol.shape[0]], spacing=[ps[1], ps[0], dz],
                origin=pos[0], direction=direction, data=np.transpose(vol, (2, 1, 0)), meta=meta)


def from_nifti(path):
    img = nibabel.load(path)
    aff = np.diag([-1.0, -1.0, 1.0, 1.0]) @ img.affine  # RAS -> LPS
    m = aff[:3, :3]
    spacing = np.linalg.norm(m, axis=0)
    data = np.asarray(img.get_fdata())
    return dict(dims=list(data.shape), spacing=spacing, origin=aff[:3, 3],
                direction=m / spacing, data=data)


def read_ply(path):
    """Binary little-endian PLY with double x, y, z and uchar/int face lists."""
    raw = pathlib.Path(path).read_bytes()
    end = raw.index(b"end_header\n") + len(b"end_header\n")
    header = raw[:end].decode().splitlines()
    if "format binary_little_endian 1.0" not in header:
        fail(f"{path}: not binary little-endian")
    counts = {l.split()[1]: int(l.split()[2]) for l in header if l.startswith("element")}
    nv, nf = counts["vertex"], counts["face"]
    verts = np.frombuffer(raw, dtype="<f8", count=3 * nv, offset=end).reshape(nv, 3)
    faces = np.frombuffer(raw, dtype=np.dtype([("n", "u1"), ("v", "<i4", 3)]), count=nf,
                          offset=end + 24 * nv)
    if not (faces["n"] == 3).all():
        fail(f"{path}: not all faces are triangles")
    return verts, faces["v"]


def point_mesh_distance(p, verts, tris):
    """Exact distance from p to a triangle mesh (closest point per triangle, vectorised)."""
    a, b, c = verts[tris[:, 0]], verts[tris[:, 1]], verts[tris[:, 2]]
    ab, ac, ap = b - a, c - a, p - a
    n = np.cross(ab, ac)
    nn = np.einsum("ij,ij->i", n, n)
    # barycentric coordinates of the projection
    v = np.einsum("ij,ij->i", np.cross(ap, ac), n) / nn
    w = np.einsum("ij,ij->i", np.cross(ab, ap), n) / nn
    inside = (v >= 0) & (w >= 0) & (v + w <= 1)
    plane = np.abs(np.einsum("ij,ij->i", ap, n)) / np.sqrt(nn)
    best = np.min(plane[inside]) if inside.any() else np.inf

    def seg(x, y):
        d = y - x
        t = np.clip(np.einsum("ij,ij->i", p - x, d) / np.einsum("ij,ij->i", d, d), 0, 1)
        return np.linalg.norm(x + d * t[:, None] - p, axis=1)

    return min(best, seg(a, b).min(), seg(b, c).min(), seg(c, a).min())


def main():
    case = pathlib.Path(sys.argv[1])
    truth = json.loads((case / "truth.json").read_text())
    g = truth["image"]
    expected_dir = np.array(g["direction"], float).reshape(3, 3)
    dicom = from_dicom(case / "dicom")
    image = from_nifti(case / "image.nii.gz")
    labels = from_nifti(case / "segmentation" / "labels.nii.gz")
    for name, got in (("pydicom", dicom), ("nibabel image", image), ("nibabel labels", labels)):
        if list(got["dims"]) != g["dims"]:
            fail(f"{name} dims {got['dims']} != {g['dims']}")
        close(got["spacing"], g["spacing_mm"], 1e-5, f"{name} spacing")
        close(got["origin"], g["origin"], 1e-4, f"{name} origin")
        close(got["direction"], expected_dir, 1e-6, f"{name} direction")
    if not np.array_equal(dicom["data"], image["data"]):
        fail(f"DICOM and NIfTI voxels differ (max {np.abs(dicom['data'] - image['data']).max()})")
    meta = dicom["meta"]
    side = "L" if truth["side"] == "left" else "R"
    if meta["sop_class"] != "1.2.840.10008.5.1.4.1.1.2":
        fail(f"SOP class {meta['sop_class']} is not CT Image Storage")
    if (meta["laterality"], meta["image_laterality"]) != ("absent", side):
        fail(f"laterality {meta['laterality']}/{meta['image_laterality']} != {side}")
    if not (meta["patient_name"] and meta["patient_id"] and len(meta["birth_date"]) == 8):
        fail(f"missing fake patient identity: {meta}")
    if len(meta["uids"]) != 3:
        fail(f"series, study and frame of reference UIDs not one each: {meta['uids']}")
    present = sorted(int(v) for v in np.unique(labels["data"]))
    if present != [0, 1, 2, 3, 4]:
        fail(f"label values {present} != [0, 1, 2, 3, 4]")
    # bone labels sit on bright voxels, on average
    for label, name in ((1, "malleus"), (2, "incus")):
        mean = image["data"][labels["data"] == label].mean()
        if mean < 500:
            fail(f"{name} label voxels average {mean:.0f} HU, not bone")

    surfaces = {n: read_ply(case / "segmentation" / f"{n}.ply")
                for n in ("malleus", "incus", "stapes", "eardrum")}
    lm = {k: np.array(v, float) for k, v in truth["landmarks"].items()}
    checks = [("incudomalleolar", "malleus", 0.3), ("incudomalleolar", "incus", 0.3),
              ("incudostapedial", "incus", 0.65), ("incudostapedial", "stapes", 0.65),
              ("umbo", "malleus", 0.3), ("umbo", "eardrum", 0.05)]
    for point, surface, most in checks:
        d = point_mesh_distance(lm[point], *surfaces[surface])
        if d > most:
            fail(f"{point} is {d:.3f} mm from the {surface} surface (at most {most})")
        print(f"{point} to {surface}: {d:.3f} mm")
    picked = {k: np.array(v, float) for k, v in truth["landmarks_picked"].items()}
    fcsv = {}
    for line in (case / "landmarks.fcsv").read_text().splitlines():
        if not line.startswith("#"):
            f = line.split(",")
            fcsv[f[11]] = np.array(f[1:4], float)
    for k in lm:
        close(fcsv[k], picked[k], 1e-4, f"landmarks.fcsv {k}")
        if np.linalg.norm(picked[k] - lm[k]) > 0.3 + 1e-9:
            fail(f"pick noise of {k} exceeds 0.3 mm")
    print("pydicom, nibabel: ok")


main()
