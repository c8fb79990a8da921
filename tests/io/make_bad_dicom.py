#!/usr/bin/python3
"""Builds a damaged copy of a DICOM series for the hostile-input tests.

usage: make_bad_dicom.py CASE SOURCE_DIR DEST_DIR

Copies every file of SOURCE_DIR into DEST_DIR (created, must not exist) and then damages the
copy as CASE says. Tags are edited with pydicom (Debian python3-pydicom); pixel data is never
decoded, so JPEG-2000 series need no codec. Prints one line naming what was changed.
"""
import os
import random
import shutil
import sys

import pydicom
from pydicom.uid import generate_uid


def slices(dest):
    """(path, dataset without pixels) sorted by position along the slice normal (z here)."""
    out = []
    for name in sorted(os.listdir(dest)):
        p = os.path.join(dest, name)
        out.append((p, pydicom.dcmread(p, stop_before_pixels=True)))
    out.sort(key=lambda t: float(t[1].ImagePositionPatient[2]))
    return out


def edit(path, fn):
    ds = pydicom.dcmread(path)
    fn(ds)
    ds.save_as(path)


def new_instance(ds):
    uid = generate_uid()
    ds.SOPInstanceUID = uid
    ds.file_meta.MediaStorageSOPInstanceUID = uid


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    case, src, dest = sys.argv[1:]
    shutil.copytree(src, dest)
    s = slices(dest)
    mid_path, mid = s[len(s) // 2]
    base = os.path.basename(mid_path)

    if case == "good":
        print("unchanged copy")
    elif case == "duplicate":
        # A second file at the same position (new SOPInstanceUID), like a re-sent slice.
        dup = os.path.join(dest, base + ".dup")
        shutil.copy(mid_path, dup)
        edit(dup, new_instance)
        print(f"duplicate of {base} at z = {mid.ImagePositionPatient[2]}")
    elif case == "missing":
        os.remove(mid_path)
        print(f"removed {base} (z = {mid.ImagePositionPatient[2]})")
    elif case == "moved":
        # One slice shifted by half a slice spacing along z.
        def move(ds):
            p = [float(v) for v in ds.ImagePositionPatient]
            p[2] += 1.0
            ds.ImagePositionPatient = p
        edit(mid_path, move)
        print(f"moved {base} by +1 mm along z")
    elif case == "random_bytes":
        # One slice replaced by random bytes of the same length (no DICOM preamble).
        n = os.path.getsize(mid_path)
        with open(mid_path, "wb") as f:
            f.write(random.Random(15).randbytes(n))
        print(f"overwrote {base} with {n} random bytes")
    elif case == "truncated":
        # One slice cut in the middle of its pixel data.
        n = os.path.getsize(mid_path)
        with open(mid_path, "r+b") as f:
            f.truncate(n // 2)
        print(f"truncated {base} to {n // 2} bytes")
    elif case == "same_position":
        z = s[0][1].ImagePositionPatient
        for p, _ in s:
            edit(p, lambda ds: setattr(ds, "ImagePositionPatient", list(z)))
        print(f"every slice at {list(z)}")
    elif case == "oblique":
        # One slice tilted by about 10 degrees about x.
        edit(mid_path, lambda ds: setattr(ds, "ImageOrientationPatient", [1, 0, 0, 0, 0.98480775, 0.17364818]))
        print(f"{base}: ImageOrientationPatient tilted")
    elif case == "no_position":
        def drop(ds):
            del ds.ImagePositionPatient
        edit(mid_path, drop)
        print(f"{base}: ImagePositionPatient removed")
    elif case == "zero_spacing":
        for p, _ in s:
            edit(p, lambda ds: setattr(ds, "PixelSpacing", [0, 0]))
        print("PixelSpacing 0\\0 in every slice")
    elif case == "nan_spacing":
        def nan(ds):
            ds["PixelSpacing"].value = "NaN\\NaN"
        for p, _ in s:
            edit(p, nan)
        print("PixelSpacing NaN\\NaN in every slice")
    elif case == "other_size":
        # One slice claims a different matrix size (its pixel data no longer matches).
        edit(mid_path, lambda ds: setattr(ds, "Columns", 256))
        print(f"{base}: Columns 256")
    elif case == "no_intercept":
        # One slice without RescaleIntercept (0028,1052): its pixels would be read 1024 HU too bright.
        def drop(ds):
            del ds.RescaleIntercept
        edit(mid_path, drop)
        print(f"{base}: RescaleIntercept removed")
    elif case == "no_slope":
        def drop(ds):
            del ds.RescaleSlope
        edit(mid_path, drop)
        print(f"{base}: RescaleSlope removed")
    elif case == "named_beside_empty":
        # The series (empty SeriesInstanceUID) plus a copy of it under a real SeriesInstanceUID.
        uid = generate_uid()
        for p, _ in s:
            copy = os.path.join(dest, "named_" + os.path.basename(p))
            shutil.copy(p, copy)
            def rename(ds):
                ds.SeriesInstanceUID = uid
                new_instance(ds)
            edit(copy, rename)
        print(uid)
    elif case == "stray_file":
        # A non-DICOM file beside the series (a note someone left there).
        with open(os.path.join(dest, "notes.txt"), "w") as f:
            f.write("scanned on Tuesday\n")
        print("added notes.txt")
    else:
        sys.exit(f"unknown case {case}")


if __name__ == "__main__":
    main()
