#!/usr/bin/env python3
"""Makes the HDF5 reproducers of this directory from the fuzz seeds (standard library only).

A NetCDF-4 file keeps the DIMENSION_LIST of each variable as variable-length
references into HDF5's global heap, a collection "GCOL" of objects (index, 2
bytes; reference count, 2; reserved, 4; size, 8; data).  HDF5 1.10.8 trusts
the sizes it finds there (docs/validation.md, "Fuzzing and sanitizers"):

  segv OBJECT  the size of that object set to 1.66e18: H5HG_read copies that
               many bytes (a segmentation fault; AddressSanitizer reports the
               memcpy);
  loop         the header of the first object zeroed (index 0, size 0): the
               heap's parser steps by the size it reads and loops for ever.

  python3 damage_global_heap.py SEED OUT segv OBJECT | loop
"""
import struct
import sys

HUGE_SIZE = 1657324662872342536  # the size the fuzzer had written into the first reproducer


def heap_objects(data):
    """Offsets of the objects of the first global heap collection (the free space last)."""
    start = data.find(b"GCOL")
    if start < 0:
        sys.exit("no global heap collection (GCOL) in the file")
    (size,) = struct.unpack_from("<Q", data, start + 8)
    offsets, at = [], start + 16
    while at < start + size:
        index, _ = struct.unpack_from("<HH", data, at)
        (length,) = struct.unpack_from("<Q", data, at + 8)
        offsets.append(at)
        if index == 0:
            break
        at += 16 + (length + 7) // 8 * 8
    return offsets


def main():
    seed, out, mode = sys.argv[1:4]
    data = bytearray(open(seed, "rb").read())
    objects = heap_objects(bytes(data))
    if mode == "segv":
        struct.pack_into("<Q", data, objects[int(sys.argv[4])] + 8, HUGE_SIZE)
    elif mode == "loop":
        data[objects[0]:objects[0] + 16] = bytes(16)
    else:
        sys.exit(__doc__)
    open(out, "wb").write(data)


if __name__ == "__main__":
    main()
