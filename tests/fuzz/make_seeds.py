#!/usr/bin/python3
"""make_seeds.py — writes the fuzz harnesses' seed corpora (tests/fuzz/seeds/<harness>/): small
valid files of every kind and encoding each loader reads, plus a few near misses, in the input
layout each harness expects (see the fuzz_*.cpp banners). Run it again after changing a layout."""
import gzip
import io
import json
import os
import struct
import sys

import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
seeds = os.path.join(here, "seeds")


def put(harness, name, data):
    d = os.path.join(seeds, harness)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def npy(array, fortran=False):
    b = io.BytesIO()
    np.save(b, np.asfortranarray(array) if fortran else array)
    return b.getvalue()


def gz(data):
    return gzip.compress(data, mtime=0)


rng = np.random.default_rng(19)
vol = rng.random((4, 3, 2)).astype(np.float32)

# .npy: float32/64, integers of both byte orders, Fortran order, 2-D and 4-D near misses.
put("npy", "f4.npy", npy(vol))
put("npy", "f8.npy", npy(vol.astype(np.float64)))
put("npy", "u1.npy", npy((vol * 255).astype(np.uint8)))
put("npy", "u2_big.npy", npy((vol * 60000).astype(">u2")))
put("npy", "i4.npy", npy((vol * 1000).astype(np.int32)))
put("npy", "fortran.npy", npy(vol, fortran=True))
put("npy", "two_d.npy", npy(vol[0]))
put("npy", "four_d.npy", npy(vol[None]))

# NRRD: first byte 0 = attached (.nrrd), 1 = detached (.nhdr, data in d.raw / d.raw.gz, which
# the harness makes from the same bytes).
raw = vol.astype("<f4").tobytes()
head = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 3 4\nendian: little\n"
put("nrrd", "raw.nrrd", b"\0" + (head + "encoding: raw\nspacings: 0.5 1 2\n\n").encode() + raw)
put("nrrd", "gzip.nrrd", b"\0" + (head + "encoding: gzip\n\n").encode() + gz(raw))
ascii_values = " ".join(repr(float(v)) for v in vol.ravel())
put("nrrd", "ascii.nrrd", b"\0" + (head + "encoding: ascii\n\n" + ascii_values).encode())
put("nrrd", "big_u16.nrrd", b"\0" + b"NRRD0005\ntype: unsigned short\ndimension: 4\nsizes: 1 2 3 4\n"
    b"endian: big\nencoding: raw\nspace directions: none (0.5,0,0) (0,1,0) (0,0,2)\n\n"
    + (vol * 60000).astype(">u2").tobytes())
put("nrrd", "detached.nhdr", b"\1" + (head + "encoding: raw\ndata file: d.raw\n").encode())
put("nrrd", "detached_gz.nhdr", b"\1" + (head + "encoding: gz\ndata file: d.raw.gz\n").encode())


def nifti_header(datatype, bitpix, dims, vox_offset, magic, big=False, slope=0.0, inter=0.0):
    e = ">" if big else "<"
    h = bytearray(348)
    struct.pack_into(e + "i", h, 0, 348)
    struct.pack_into(e + "8h", h, 40, 3, *dims, 1, 1, 1, 1)
    struct.pack_into(e + "hh", h, 70, datatype, bitpix)
    struct.pack_into(e + "4f", h, 76, 1, 0.5, 1, 2)
    struct.pack_into(e + "3f", h, 108, vox_offset, slope, inter)
    h[344:348] = magic
    return bytes(h)


# NIfTI: first byte 0 = .nii, 1 = .nii.gz, 2 = .hdr (with .img of the same bytes beside it).
i16 = (vol * 1000).astype("<i2").tobytes()
nii = nifti_header(4, 16, (2, 3, 4), 352, b"n+1\0") + b"\0" * 4 + i16
put("nifti", "int16.nii", b"\0" + nii)
put("nifti", "int16.nii.gz", b"\1" + gz(nii))
f4_big = nifti_header(16, 32, (2, 3, 4), 352, b"n+1\0", big=True, slope=2, inter=1)
put("nifti", "float_big_scaled.nii", b"\0" + f4_big + b"\0" * 4 + vol.astype(">f4").tobytes())
pair = nifti_header(2, 8, (2, 3, 4), 0, b"ni1\0")
put("nifti", "pair.hdr", b"\2" + pair)  # its .img is these bytes too: a size mismatch to report

# raw: dims X, Y, Z as uint16, type index (uint8 int8 uint16 int16 uint32 int32 float32 float64
# complex), flags (1 = big endian, 2 = range from the next 16 bytes), 16 bytes of range, data.
def raw_input(dims, type_index, flags, data, lo=0.0, hi=1.0):
    return struct.pack("<3HBB", *dims, type_index, flags) + struct.pack("<2d", lo, hi) + data


put("raw", "f32.raw", raw_input((2, 3, 4), 6, 0, raw))
put("raw", "u16_big_range.raw", raw_input((2, 3, 4), 2, 3, (vol * 60000).astype(">u2").tobytes(),
                                          100, 50000))
put("raw", "u8_claims_more.raw", raw_input((65535, 65535, 65535), 0, 0, b"\1" * 24))
put("raw", "f64.raw", raw_input((2, 3, 4), 7, 2, vol.astype("<f8").tobytes(), -1, 2))

# .cvol: "cvol", dims (3 × uint64), voxel size (3 × double), type (int32), compressed flag, pad.
def cvol(dims, voxel, code, data, compressed=0):
    h = b"cvol" + struct.pack("<3Q", *dims) + struct.pack("<3d", *voxel) + struct.pack("<i", code)
    h += bytes([compressed]) + b"\0" * (64 - len(h) - 1)
    return h + data


put("cvol", "float.cvol", cvol((2, 3, 4), (1, 1, 1), 2, raw))
put("cvol", "u8.cvol", cvol((2, 3, 4), (0.5, 1, 2), 0, (vol * 255).astype(np.uint8).tobytes()))
put("cvol", "u16.cvol", cvol((2, 3, 4), (1, 1, 1), 1, (vol * 60000).astype("<u2").tobytes()))
put("cvol", "lz4.cvol", cvol((2, 3, 4), (1, 1, 1), 2, raw, compressed=1))

# Scene JSON: the examples' scenes, and scenes naming the harness's vol.npy.
examples = os.path.join(here, "..", "..", "examples", "scenes")
for name in sorted(os.listdir(examples)):
    with open(os.path.join(examples, name), "rb") as f:
        put("scene_json", name, f.read())
camera = {"eye": [1.2, 0.9, 1.6], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40,
          "width": 8, "height": 8}
tfs = [
    {"type": "piecewise_linear", "points": [
        {"density": 0.0, "color": [0, 0, 0], "extinction": 0},
        {"density": 1.0, "color": [1, 1, 1], "extinction": 8}]},
    {"type": "gaussian", "gaussians": [
        {"mean": 0.5, "width": 0.1, "color": [1, 0.5, 0.2], "extinction": 3}]},
    {"type": "table", "range": [0, 1], "entries": [[0, 0, 0, 0], [1, 1, 1, 4]]},
    {"type": "identity", "extinction_scale": 2},
]
put("scene_json", "file_volume.json", json.dumps({
    "volume": {"file": "vol.npy", "range": [0, 1], "spacing": [1, 1, 2]},
    "model": "absorption", "tf": tfs[0], "cameras": [camera],
    "integrator": {"scheme": "midpoint", "step": 0.5}}))
put("scene_json", "orbit.json", json.dumps({
    "volume": {"synthetic": "marschner_lobb", "dims": [8, 8, 8]},
    "model": "emission_absorption", "tf": tfs[1],
    "cameras": [{"orbit": {"count": 3, "radius": 2, "elevation": 20}, "width": 8, "height": 8,
                 "fov_y": 30}]}))

# The parts on their own: TFs, camera lists, integrators, inline volumes.
for i, tf in enumerate(tfs):
    put("tf_json", f"tf_{tf['type']}.json", json.dumps(tf))
put("tf_json", "cameras.json", json.dumps([camera, {"orbit": {"count": 2, "radius": 3},
                                                    "width": 4, "height": 4}]))
put("tf_json", "camera_lens.json", json.dumps([dict(camera, projection="orthographic",
                                                    ortho_height=2)]))
for scheme in ("midpoint", "endpoints", "exact", "preintegrated"):
    put("tf_json", f"integrator_{scheme}.json", json.dumps({"scheme": scheme, "step": 0.25}))
put("tf_json", "volume_synthetic.json", json.dumps({"synthetic": "sphere", "dims": [4, 4, 4]}))
put("tf_json", "volume_file.json", json.dumps({"file": "vol.npy"}))

print(f"make_seeds: wrote {sum(len(fs) for _, _, fs in os.walk(seeds))} seeds under {seeds}")
