#!/usr/bin/python3
"""Writes a small volume file with one hostile property, for the hostile-input tests.

usage: make_bad_volume.py CASE OUT_FILE

The files are written byte by byte with the standard library (struct, gzip), independently of
hpcm and ITK, following the NIfTI-1, MetaImage and NRRD formats. Volumes are 10x10x10, 2 mm,
40 HU unless the case says otherwise. Cases:
  nifti_nan, nifti_inf (.nii or .nii.gz): float32 data with one NaN / +Inf voxel
  nifti_pixdim_zero, nifti_pixdim_nan, nifti_pixdim_negative: pixdim[1] = 0 / NaN / -2
  nifti_ok: a valid float32 file (control)
  nifti_hu_huge: one voxel at 3e7 HU;  nifti_hu_padding: one voxel at -30000 HU
  mha_spacing_zero, mha_spacing_nan, mha_spacing_negative, mha_ok (.mha, data inline)
  nrrd_spacing_zero, nrrd_spacing_nan, nrrd_direction_nan, nrrd_ok (.nrrd, data inline)
"""
import gzip
import math
import struct
import sys

N = 10
NVOX = N * N * N


def nifti(path, data_f32, pixdim=(2.0, 2.0, 2.0)):
    hdr = bytearray(348)
    struct.pack_into("<i", hdr, 0, 348)
    struct.pack_into("<8h", hdr, 40, 3, N, N, N, 1, 1, 1, 1)
    struct.pack_into("<hh", hdr, 70, 16, 32)  # FLOAT32
    struct.pack_into("<8f", hdr, 76, 1.0, *pixdim, 1, 1, 1, 1)
    struct.pack_into("<f", hdr, 108, 352.0)  # vox_offset
    struct.pack_into("<ff", hdr, 112, 1.0, 0.0)  # scl_slope, scl_inter
    struct.pack_into("<hh", hdr, 252, 0, 0)  # qform_code, sform_code: pixdim alone gives the grid
    hdr[344:348] = b"n+1\0"
    body = bytes(hdr) + b"\0\0\0\0" + struct.pack(f"<{NVOX}f", *data_f32)
    if path.endswith(".gz"):
        body = gzip.compress(body)
    with open(path, "wb") as f:
        f.write(body)


def mha(path, spacing):
    data = struct.pack(f"<{NVOX}h", *([40] * NVOX))
    head = (
        "ObjectType = Image\nNDims = 3\nDimSize = 10 10 10\nElementType = MET_SHORT\n"
        f"ElementSpacing = {spacing}\nElementByteOrderMSB = False\nElementDataFile = LOCAL\n"
    )
    with open(path, "wb") as f:
        f.write(head.encode() + data)


def nrrd(path, directions):
    data = struct.pack(f"<{NVOX}h", *([40] * NVOX))
    head = (
        "NRRD0004\ntype: short\ndimension: 3\nspace: left-posterior-superior\nsizes: 10 10 10\n"
        f"{directions}\nendian: little\nencoding: raw\n\n"
    )
    with open(path, "wb") as f:
        f.write(head.encode() + data)


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    case, out = sys.argv[1:]
    vox = [40.0] * NVOX
    if case == "nifti_nan":
        vox[345] = math.nan
        nifti(out, vox)
    elif case == "nifti_inf":
        vox[7] = math.inf
        nifti(out, vox)
    elif case == "nifti_pixdim_zero":
        nifti(out, vox, (0.0, 2.0, 2.0))
    elif case == "nifti_pixdim_nan":
        nifti(out, vox, (math.nan, 2.0, 2.0))
    elif case == "nifti_pixdim_negative":
        nifti(out, vox, (-2.0, 2.0, 2.0))
    elif case == "nifti_ok":
        vox[0] = -1000.0
        nifti(out, vox)
    elif case == "nifti_hu_huge":
        vox[0] = -1000.0
        vox[1] = 3e7
        nifti(out, vox)
    elif case == "nifti_hu_padding":
        vox[0] = -30000.0
        nifti(out, vox)
    elif case == "mha_spacing_zero":
        mha(out, "0 2 2")
    elif case == "mha_spacing_nan":
        mha(out, "nan 2 2")
    elif case == "mha_spacing_negative":
        mha(out, "-2 2 2")
    elif case == "mha_ok":
        mha(out, "2 2 2")
    elif case == "nrrd_spacing_zero":
        nrrd(out, "spacings: 0 2 2")
    elif case == "nrrd_spacing_nan":
        nrrd(out, "spacings: nan 2 2")
    elif case == "nrrd_direction_nan":
        nrrd(out, "space directions: (nan,0,0) (0,2,0) (0,0,2)")
    elif case == "nrrd_ok":
        nrrd(out, "space directions: (2,0,0) (0,2,0) (0,0,2)")
    else:
        sys.exit(f"unknown case {case}")


if __name__ == "__main__":
    main()
