"""VTK XML image data (.vti, issue 57's time series): every layout VTK's writer makes is read back exactly (raw and
zlib-compressed appended data, UInt32 and UInt64 headers, both byte orders, extents not starting at 0, a
Direction), malformed files are refused naming the file and the problem, and the shared viscous-fingering run
reads with the value range its headers declare."""
import glob
import os
import re
import struct
import zlib

import numpy as np
import pytest

import volrig

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "timevarying",
                    "viscous_fingers_run01")
VTK_TYPES = {"float32": "Float32", "float64": "Float64", "int16": "Int16", "uint8": "UInt8", "int32": "Int32",
             "uint16": "UInt16", "int64": "Int64"}


def vti_bytes(a, *, spacing=(1, 1, 1), origin=(0, 0, 0), start=(0, 0, 0), zlib_blocks=None, header64=False,
              big=False, name="v", direction=None, extra_arrays=0):
    """A .vti as VTK's writer lays it out: ``a`` [z, y, x] appended raw; ``zlib_blocks``: the block size of
    vtkZLibDataCompressor (None: uncompressed). ``extra_arrays`` other point arrays are written before it."""
    a = np.ascontiguousarray(a)
    order = ">" if big else "<"
    word = order + ("Q" if header64 else "I")
    payload = a.astype(a.dtype.newbyteorder(order)).tobytes()

    def block(data):
        if zlib_blocks is None:
            return struct.pack(word, len(data)) + data
        parts = [data[i:i + zlib_blocks] for i in range(0, len(data), zlib_blocks)]
        packed = [zlib.compress(p) for p in parts]
        last = len(parts[-1]) if len(parts[-1]) != zlib_blocks else 0
        return struct.pack(order + ("Q" if header64 else "I") * (3 + len(parts)), len(parts), zlib_blocks, last,
                           *map(len, packed)) + b"".join(packed)

    arrays, blobs, offset = [], [], 0
    for k in range(extra_arrays + 1):
        data = payload if k == extra_arrays else np.zeros_like(a).tobytes()
        b = block(data)
        n = name if k == extra_arrays else f"other{k}"
        arrays.append(f'<DataArray type="{VTK_TYPES[a.dtype.name]}" Name="{n}" format="appended" '
                      f'offset="{offset}"/>')
        blobs.append(b)
        offset += len(b)
    nz, ny, nx = a.shape
    ext = f"{start[0]} {start[0] + nx - 1} {start[1]} {start[1] + ny - 1} {start[2]} {start[2] + nz - 1}"
    d = "" if direction is None else ' Direction="' + " ".join(map(str, np.ravel(direction))) + '"'
    head = (f'<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0" '
            f'byte_order="{"BigEndian" if big else "LittleEndian"}" header_type="{"UInt64" if header64 else "UInt32"}"'
            + (' compressor="vtkZLibDataCompressor"' if zlib_blocks else "") + ">\n"
            f'  <ImageData WholeExtent="{ext}" Origin="{" ".join(map(str, origin))}" '
            f'Spacing="{" ".join(map(str, spacing))}"{d}>\n    <Piece Extent="{ext}">\n'
            f'      <PointData Scalars="{name}">\n        ' + "\n        ".join(arrays) +
            '\n      </PointData>\n      <CellData>\n      </CellData>\n    </Piece>\n  </ImageData>\n'
            '  <AppendedData encoding="raw">\n   _')
    return head.encode() + b"".join(blobs) + b"\n  </AppendedData>\n</VTKFile>\n"


def write(tmp_path, data, name="a.vti"):
    p = tmp_path / name
    p.write_bytes(data)
    return str(p)


@pytest.mark.parametrize("dtype", ["float32", "float64", "int16", "uint8", "int64"])
@pytest.mark.parametrize("layout", [dict(), dict(header64=True), dict(big=True), dict(zlib_blocks=4096),
                                    dict(zlib_blocks=1000, header64=True, big=True), dict(zlib_blocks=1 << 15)])
def test_every_layout_reads_back_exactly(tmp_path, dtype, layout):
    rng = np.random.default_rng(5)
    a = (rng.normal(size=(7, 9, 11)) * 50).astype(dtype)
    v = volrig.load(write(tmp_path, vti_bytes(a, spacing=(0.5, 2, 3), origin=(1, 2, 3), extra_arrays=1, **layout)))
    assert v.array.dtype == np.dtype(dtype)
    np.testing.assert_array_equal(v.array, a)
    assert v.spacing == (0.5, 2.0, 3.0) and v.origin == (1.0, 2.0, 3.0)


def test_extent_start_and_direction_place_voxel_zero(tmp_path):
    a = np.arange(24, dtype=np.float32).reshape(2, 3, 4)
    turn = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]  # x axis along world +y, y along -x
    v = volrig.load(write(tmp_path, vti_bytes(a, spacing=(2, 3, 4), origin=(10, 20, 30), start=(5, 6, 7),
                                              direction=turn)))
    np.testing.assert_array_equal(v.array, a)
    # voxel (0, 0, 0) is extent index (5, 6, 7): Origin + Direction * (Spacing * index)
    np.testing.assert_allclose(v.origin, np.array([10, 20, 30]) + np.array(turn) @ np.array([10, 18, 28]))
    np.testing.assert_allclose(v.direction, turn)


def test_the_active_scalars_are_read(tmp_path):
    a = np.ones((2, 2, 2), np.float32)
    data = vti_bytes(a, name="density", extra_arrays=2)
    assert volrig.load(write(tmp_path, data)).array.sum() == 8  # the others are zeros
    unnamed = data.replace(b' Scalars="density"', b"")  # no active scalars: the first array
    assert volrig.load(write(tmp_path, unnamed, "b.vti")).array.sum() == 0


GOOD = vti_bytes(np.arange(60, dtype=np.float32).reshape(3, 4, 5), zlib_blocks=64)


@pytest.mark.parametrize("change, message", [
    (lambda b: b[:-60], r"past the end|truncated"),
    (lambda b: b.replace(b'WholeExtent="0 4', b'WholeExtent="0 40000000'), r"Extent differs|past the end|block table"),
    (lambda b: b.replace(b"0 4 0 3 0 2", b"0 4 0 3 0 200000000"),
     r"5x4x200000001 float32 voxels need 16,000,000,080 bytes from a file of .* refused as broken"),
    (lambda b: b.replace(b"0 4 0 3 0 2", b"0 nan 0 3 0 2"), r"WholeExtent .* is not 6 finite numbers"),
    (lambda b: b.replace(b"0 4 0 3 0 2", b"4 0 0 3 0 2"), r"not three whole ranges"),
    (lambda b: b.replace(b'Spacing="1 1 1"', b'Spacing="1 0 1"'), r"spacing"),
    (lambda b: b.replace(b'Float32', b'Bit'), r"type 'Bit' is not a number type"),
    (lambda b: b.replace(b'format="appended"', b'format="ascii"'), r"stored 'ascii': only appended data"),
    (lambda b: b.replace(b'offset="0"', b'offset="99999999"'), r"offset runs past the end"),
    (lambda b: b.replace(b'offset="0"', b'offset="-3"'), r"offset '-3' is not a byte offset"),
    (lambda b: b.replace(b'compressor="vtkZLibDataCompressor"', b'compressor="vtkLZ4DataCompressor"'),
     r"compressor 'vtkLZ4DataCompressor' is not read"),
    (lambda b: b.replace(b'type="ImageData"', b'type="PolyData"'), r"only ImageData"),
    (lambda b: b.replace(b"<AppendedData", b"<Appended"), r"no <AppendedData>"),
    (lambda b: b.replace(b'<DataArray type="Float32"', b'<DataArray NumberOfComponents="3" type="Float32"'),
     r"3' components: only scalars"),
    (lambda b: b"\0" * 100, r"not a VTK XML file"),
])
def test_malformed_files_are_refused_naming_the_file(tmp_path, change, message):
    f = write(tmp_path, change(GOOD))
    with pytest.raises(volrig.VolrigError, match=message) as e:
        volrig.load(f)
    assert str(e.value).startswith(f)


def test_lying_block_tables_are_refused(tmp_path):
    mark = b'encoding="raw">\n   _'
    head, _, rest = GOOD.partition(mark)
    words = list(struct.unpack_from("<3I", rest))
    for k, value in ((0, 99), (1, 7), (2, 65)):  # block count, block size, last block's size
        w = list(words)
        w[k] = value
        with pytest.raises(volrig.FileFormatError, match="block table"):
            volrig.load(write(tmp_path, head + mark + struct.pack("<3I", *w) + rest[12:], f"t{k}.vti"))
    swapped = bytearray(rest)
    struct.pack_into("<I", swapped, 12, 10 ** 6)  # the first block's compressed size beyond the file
    with pytest.raises(volrig.FileFormatError, match="run past the end"):
        volrig.load(write(tmp_path, head + mark + bytes(swapped), "c.vti"))


@pytest.mark.skipif(not os.path.isdir(DATA), reason="../shared/data/timevarying is absent")
def test_the_viscous_fingering_run_reads_with_its_declared_ranges():
    files = sorted(glob.glob(os.path.join(DATA, "*.vti")))
    assert len(files) == 30
    for f in files[::7]:
        v = volrig.load(f)
        assert v.dims == (64, 64, 64) and v.array.dtype == np.float32
        with open(f, "rb") as fh:
            head = fh.read(2000).decode("latin-1")
        lo, hi = (float(re.search(k + r'="([^"]+)"', head).group(1)) for k in ("RangeMin", "RangeMax"))
        assert v.array.min() == pytest.approx(lo, abs=1e-5) and v.array.max() == pytest.approx(hi, rel=1e-7)


def test_a_one_byte_array_at_the_very_end_reads(tmp_path):
    """An uncompressed array needs only its byte count before it (not a block table's three words)."""
    data = vti_bytes(np.array([[[7]]], np.uint8))
    data = data[:data.rindex(b"\n  </AppendedData>")]  # the closing tags are not needed to read
    assert volrig.load(write(tmp_path, data)).array.tolist() == [[[7]]]
