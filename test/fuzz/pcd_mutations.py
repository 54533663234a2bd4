"""Hypothesis strategies that damage valid PCD files: the PCD reader's fuzzing input.

Seeds are valid files in every format (written here, and PCL's own files from ../shared/data
when present); a mutation truncates, flips, inserts or deletes bytes, rewrites a header value or
forges a binary_compressed block's sizes. Used by test/unit/test_pcd_fuzz.py (a short bounded
run) and tools/fuzz_pcd.py (a long one).
"""
import pathlib
import struct

import numpy as np
from hypothesis import strategies as st

HEADER_KEYS = (b"VERSION", b"FIELDS", b"SIZE", b"TYPE", b"COUNT", b"WIDTH", b"HEIGHT", b"VIEWPOINT", b"POINTS", b"DATA")
SHARED_DATA = pathlib.Path(__file__).resolve().parents[3] / "shared" / "data"


def seed_files(directory):
    """Valid PCD files to mutate: small organized and unorganized clouds in every format, plus PCL's."""
    from example_pcl import conversions, pcd

    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(4, 5, 3)).astype(np.float32)
    xyz[1, 2] = np.nan
    rgb = rng.integers(0, 256, (4, 5, 3), dtype=np.uint8)
    fields = [("x", 0, 7, 1), ("y", 4, 7, 1), ("z", 8, 7, 1), ("intensity", 12, 2, 1), ("hist", 14, 4, 3)]
    odd = np.zeros(7, conversions.fields_to_dtype(fields, 24))
    odd["x"] = rng.normal(size=7)
    seeds = []
    for fmt in pcd.FORMATS:
        for name, points in (("organized", conversions.make_points(xyz, rgb)), ("odd", odd)):
            path = pathlib.Path(directory) / f"{name}_{fmt}.pcd"
            pcd.write_pcd(path, points, fmt=fmt)
            seeds.append(path.read_bytes())
    for name in ("milk.pcd", "sac_plane_test.pcd"):
        if (SHARED_DATA / name).is_file():
            seeds.append((SHARED_DATA / name).read_bytes())
    return seeds


def _header_end(data):
    i = data.find(b"\nDATA ")
    if i < 0:
        return len(data)
    j = data.find(b"\n", i + 1)
    return len(data) if j < 0 else j + 1


def apply(data, mutation):
    """The file bytes after one mutation (kind, fraction in [0, 1], payload)."""
    kind, where, payload = mutation
    pos = int(where * len(data))
    if kind == "truncate":
        return data[:pos]
    if kind == "flip":
        if not data:
            return data
        pos = min(pos, len(data) - 1)
        return data[:pos] + bytes([data[pos] ^ (payload[0] if payload else 0xFF)]) + data[pos + 1:]
    if kind == "insert":
        return data[:pos] + payload + data[pos:]
    if kind == "delete":
        return data[:pos] + data[pos + 1 + len(payload):]
    if kind == "header":
        key = HEADER_KEYS[payload[0] % len(HEADER_KEYS)] if payload else b"POINTS"
        start = data.find(b"\n" + key + b" ")
        if start < 0:
            return data
        end = data.find(b"\n", start + 1)
        return data[:start + 1] + key + b" " + payload[1:] + data[end:]
    if kind == "compressed_sizes":
        start = _header_end(data)
        sizes = struct.pack("<II", *(int.from_bytes(payload[i:i + 4].ljust(4, b"\0"), "little") for i in (0, 4)))
        return data[:start] + sizes + data[start + 8:]
    raise ValueError(kind)


header_values = st.one_of(
    st.integers(-2**40, 2**40).map(lambda n: str(n).encode()),
    st.lists(st.sampled_from([b"x", b"y", b"z", b"rgb", b"F", b"U", b"I", b"4", b"8", b"0", b"1", b"-1",
                              b"binary", b"ascii", b"binary_compressed", b"nan", b"_"]), max_size=6).map(b" ".join),
    st.binary(max_size=12),
)
mutation = st.one_of(
    st.tuples(st.just("truncate"), st.floats(0, 1), st.just(b"")),
    st.tuples(st.just("flip"), st.floats(0, 1), st.binary(min_size=1, max_size=1)),
    st.tuples(st.just("insert"), st.floats(0, 1), st.binary(min_size=1, max_size=16)),
    st.tuples(st.just("delete"), st.floats(0, 1), st.binary(max_size=16)),
    st.tuples(st.just("header"), st.floats(0, 1),
              st.tuples(st.integers(0, 255), header_values).map(lambda t: bytes([t[0]]) + t[1])),
    st.tuples(st.just("compressed_sizes"), st.floats(0, 1), st.binary(min_size=8, max_size=8)),
)
mutations = st.lists(mutation, min_size=1, max_size=4)
