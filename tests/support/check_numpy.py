"""Loads drape's NPY and NPZ results with NumPy and checks them against the JSON result of the
same run: shape, dtype, and every value bit for bit in the run's precision.

usage: check_numpy.py RESULT.json RESULT.npy RESULT.npz
Exits non-zero with a message on the first difference.
"""
import json
import sys
import zipfile

import numpy as np


def main(json_path, npy_path, npz_path):
    with open(json_path) as f:
        result = json.load(f)
    frames = result["frames"] if "frames" in result else [result["final"]]
    precision = result["stats"]["precision"]
    dtype = np.dtype("<f4" if precision == "f32" else "<f8")
    particles = result["mesh"]["particles"]
    springs = result["mesh"]["springs"]

    def same(name, array, expected, dtype, shape):
        expected = np.asarray(expected, dtype=np.float64).astype(dtype).reshape(shape)
        assert array.dtype == dtype, f"{name}: dtype {array.dtype}, expected {dtype}"
        assert array.shape == shape, f"{name}: shape {array.shape}, expected {shape}"
        bits = np.uint32 if dtype.itemsize == 4 else np.uint64
        differ = np.count_nonzero(array.view(bits) != expected.view(bits))
        assert differ == 0, f"{name}: {differ} values differ from the JSON"
        print(f"{name}: {array.dtype} {array.shape} matches the JSON")

    vectors = (len(frames), particles, 3)
    same("npy positions", np.load(npy_path), [f["positions"] for f in frames], dtype, vectors)

    with zipfile.ZipFile(npz_path) as z:
        assert z.testzip() is None, "an NPZ entry fails its CRC-32"
        stored = all(i.compress_type == zipfile.ZIP_STORED for i in z.infolist())
        assert stored, "NPZ entries are stored"
    archive = np.load(npz_path)
    present = sorted(k for k in ["positions", "velocities", "normals", "energy", "strain"] if k in frames[0])
    assert sorted(archive.files) == sorted(present + ["times"]), f"npz holds {archive.files}, expected {present}"
    for field in ["positions", "velocities", "normals"]:
        if field in present:
            same(f"npz {field}", archive[field], [f[field] for f in frames], dtype, vectors)
    f8 = np.dtype("<f8")
    if "energy" in present:
        energy = [[f["energy"][k] for k in ("kinetic", "gravitational", "spring")] for f in frames]
        same("npz energy", archive["energy"], energy, f8, (len(frames), 3))
    if "strain" in present:
        same("npz strain", archive["strain"], [f["strain"] for f in frames], f8, (len(frames), springs))
    same("npz times", archive["times"], [f["t"] for f in frames], f8, (len(frames),))


if __name__ == "__main__":
    try:
        main(*sys.argv[1:])
    except AssertionError as e:
        print(f"mismatch: {e}", file=sys.stderr)
        sys.exit(1)
