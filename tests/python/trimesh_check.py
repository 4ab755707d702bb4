#!/usr/bin/env python3
"""Independent check of otoatlas' directed surface distances with trimesh.

Usage: trimesh_check.py TEST.obj REF.obj TEST_SAMPLES.txt REF_SAMPLES.txt OUT.json

Sample files hold one "x y z weight" per line. For the test samples against the reference
surface and the reference samples against the test surface, trimesh.proximity.closest_point
gives exact closest-point distances; the weighted mean, max and P95 are computed as DeepMind
surface-distance's compute_robust_hausdorff (sort by distance, cumulative normalised area,
searchsorted). OUT.json gets both directions' statistics, the per-sample distances and the
wall time of the closest-point queries.
"""
import json
import sys
import time

import numpy as np
import trimesh


def load(path):
    return trimesh.load(path, process=False, force="mesh")


def directed(mesh, samples):
    points, weights = samples[:, :3], samples[:, 3]
    start = time.perf_counter()
    _, distance, _ = trimesh.proximity.closest_point(mesh, points)
    seconds = time.perf_counter() - start
    order = np.argsort(distance, kind="stable")
    d, w = distance[order], weights[order]
    cumulative = np.cumsum(w) / np.sum(w)
    idx = np.searchsorted(cumulative, 0.95)
    return {
        "mean": float(np.sum(distance * weights) / np.sum(weights)),
        "max": float(np.max(distance)),
        "p95": float(d[min(idx, len(d) - 1)]),
        "distances": distance.tolist(),
    }, seconds


def main():
    test_path, ref_path, test_samples, ref_samples, out = sys.argv[1:6]
    test, ref = load(test_path), load(ref_path)
    a_to_b, ta = directed(ref, np.loadtxt(test_samples, ndmin=2))
    b_to_a, tb = directed(test, np.loadtxt(ref_samples, ndmin=2))
    with open(out, "w") as f:
        json.dump({"test_to_ref": a_to_b, "ref_to_test": b_to_a, "seconds": ta + tb,
                   "trimesh": trimesh.__version__}, f)


if __name__ == "__main__":
    main()
