# SPDX-License-Identifier: Apache-2.0
"""Hostile and wrong input: each psq.Error subclass, with its code and place."""

import os
import pickle

import numpy as np
import pytest

import psq
from conftest import grid_mesh


def crc32c(data: bytes) -> int:
    """CRC-32C (Castagnoli), as the .psq header checksum (spec 4.2)."""
    crc = 0xFFFFFFFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = (crc >> 1) ^ (0x82F63B78 if crc & 1 else 0)
    return crc ^ 0xFFFFFFFF


def header_end(data: bytes):
    """Offsets of the payload and of the header checksum (spec 4.2: 12-byte fixed part, varint length)."""
    at, length, shift = 12, 0, 0
    while True:
        b = data[at]
        length |= (b & 0x7F) << shift
        at += 1
        shift += 7
        if not b & 0x80:
            break
    return at, at + length


@pytest.fixture(scope="module")
def stream():
    p, f = grid_mesh(40)
    return psq.encode(p, f, bits=14, profile="compact")


def test_truncated_stream_names_the_end(stream):
    cut = stream[: len(stream) // 2]
    with pytest.raises(psq.TruncatedError) as e:
        psq.decode(cut)
    assert e.value.code == 2 and e.value.name == "truncated"
    assert e.value.offset == len(cut)
    assert isinstance(e.value, psq.Error)


def test_truncated_file_on_disk(tmp_path, stream):
    path = tmp_path / "cut.psq"
    path.write_bytes(stream[:-3])
    with pytest.raises(psq.TruncatedError) as e:
        psq.read(path)
    assert e.value.file == str(path)
    assert e.value.offset is not None and e.value.offset <= len(stream) - 3
    assert str(e.value).startswith(f"{path}: byte ")


def test_unknown_content(tmp_path):
    with pytest.raises(psq.UnknownFormatError) as e:
        psq.decode(b"this is not a mesh at all\n")
    assert e.value.code == 8 and e.value.offset == 0


def test_unsupported_version(stream):
    bad = bytearray(stream)
    bad[8] = 99
    with pytest.raises(psq.UnsupportedError) as e:
        psq.decode(bytes(bad))
    assert e.value.offset == 8


def test_payload_length_over_the_limit(stream):
    bad = bytearray(stream[:12]) + bytes([0xFF, 0xFF, 0xFF, 0x7F]) + bytes(64)
    with pytest.raises(psq.LimitError) as e:
        psq.decode(bytes(bad))
    assert e.value.code == 7 and e.value.offset is not None


def test_header_checksum(stream):
    payload, checksum = header_end(stream)
    bad = bytearray(stream)
    bad[payload + 3] ^= 0x40  # inside origin x
    with pytest.raises(psq.ChecksumError) as e:
        psq.decode(bytes(bad))
    assert e.value.code == 12 and e.value.offset is not None


def test_bad_header_with_a_valid_checksum(stream):
    payload, checksum = header_end(stream)
    bad = bytearray(stream)
    bad[payload] = 5  # position type: only 7 and 8 exist
    bad[checksum:checksum + 4] = crc32c(bytes(bad[:checksum])).to_bytes(4, "little")
    with pytest.raises(psq.BadHeaderError) as e:
        psq.decode(bytes(bad))
    assert e.value.code == 3 and e.value.offset is not None and payload <= e.value.offset <= checksum


def test_corrupt_chunk_is_an_error_with_an_offset(stream):
    _, checksum = header_end(stream)
    bad = bytearray(stream)
    at = (checksum + 4 + len(stream)) // 2
    bad[at] ^= 0xFF
    with pytest.raises(psq.Error) as e:
        psq.decode(bytes(bad))
    assert type(e.value) in (psq.ChecksumError, psq.BadValueError, psq.BadHeaderError, psq.TruncatedError)
    assert e.value.offset is not None


def test_ascii_ply_bad_value_names_the_line(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n")
    (tmp_path / "bad.ply").write_text(text)
    with pytest.raises(psq.BadValueError) as e:
        psq.read(tmp_path / "bad.ply")
    assert e.value.line == 11


def test_ply_index_out_of_range(tmp_path):
    text = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n")
    (tmp_path / "bad.ply").write_text(text)
    with pytest.raises(psq.BadIndexError) as e:
        psq.read(tmp_path / "bad.ply")
    assert e.value.code == 5 and e.value.line == 13


def test_write_checks_its_arrays(tmp_path):
    p, f = grid_mesh(4)
    bad_faces = f.copy()
    bad_faces[3, 1] = len(p)
    with pytest.raises(psq.BadIndexError):
        psq.encode(p, bad_faces)
    nan = p.copy()
    nan[2, 0] = np.nan
    with pytest.raises(psq.BadValueError) as e:
        psq.encode(nan, f)
    assert "vertex 2" in e.value.message
    with pytest.raises(psq.UsageError):
        psq.encode(p, f, bits=40)
    with pytest.raises(ValueError):  # UsageError is a ValueError too
        psq.encode(p[:, :2], f)
    with pytest.raises(psq.UsageError):
        psq.write(tmp_path / "m.xyz", p, f)
    with pytest.raises(psq.UsageError):
        psq.encode(p, f, vertex_properties={"q": np.zeros(len(p) + 1, np.float32)})
    psq.write(tmp_path / "m.psq", p, f)
    with pytest.raises(psq.UsageError):
        psq.write(tmp_path / "m.psq", p, f, overwrite=False)
    assert not list(tmp_path.glob("*.tmp*"))  # nothing half-written left behind


def test_missing_file_is_an_io_error(tmp_path):
    with pytest.raises(psq.IoError) as e:
        psq.read(tmp_path / "none.ply")
    assert e.value.code == 1 and e.value.file.endswith("none.ply")
    with pytest.raises(psq.IoError):
        psq.open(tmp_path / "none.psq")


def test_open_refuses_what_is_not_a_psq(tmp_path):
    p, f = grid_mesh(4)
    psq.write(tmp_path / "m.ply", p, f)
    with pytest.raises(psq.UnknownFormatError):
        psq.open(tmp_path / "m.ply")


def test_every_code_has_its_class_and_errors_pickle():
    classes = [psq.IoError, psq.TruncatedError, psq.BadHeaderError, psq.BadValueError, psq.BadIndexError,
               psq.UnsupportedError, psq.LimitError, psq.UnknownFormatError, psq.UsageError, psq.InternalError,
               psq.BadSequenceError, psq.ChecksumError]
    from psq import _errors, _psq
    for code, cls in enumerate(classes, start=1):
        assert cls.code == code
        assert cls.name == _psq.error_name(code)  # the library's stable names
        err = _errors._from_status(code, "message", 17, None, "f")
        assert type(err) is cls and err.offset == 17
        again = pickle.loads(pickle.dumps(err))
        assert type(again) is cls and again.offset == 17 and str(again) == str(err) == "f: byte 17: message"


@pytest.mark.parametrize("fmt", ["psq", "ply", "obj"])
def test_mutated_input_raises_psq_errors_only(tmp_path, fmt):
    """Truncations and byte flips of a valid file: a mesh or a psq.Error, never another exception or a crash."""
    p, f = grid_mesh(12)
    path = tmp_path / f"m.{fmt}"
    props = {} if fmt == "obj" else {"q": np.arange(len(p), dtype=np.uint8)}  # OBJ has no place for it
    psq.write(path, p, f, vertex_properties=props)
    good = path.read_bytes()
    rng = np.random.default_rng(7)
    outcomes = set()
    for i in range(150):
        data = bytearray(good)
        if i % 3 == 0:
            data = data[: int(rng.integers(0, len(data)))]
        else:
            for _ in range(int(rng.integers(1, 4))):
                at = int(rng.integers(0, len(data)))
                data[at] ^= 1 << int(rng.integers(0, 8))
        try:
            m = psq.decode(bytes(data))
            assert m.faces.shape[1] == 3 and (len(m.faces) == 0 or int(m.faces.max()) < len(m.positions))
            outcomes.add("mesh")
        except psq.Error as e:
            assert e.code in range(1, 13)
            outcomes.add(type(e).__name__)
        if fmt == "psq":
            try:
                with psq.open(bytes(data), chunk_triangles=16) as s:
                    for _ in s:
                        pass
            except psq.Error:
                pass
    assert len(outcomes) >= 2  # both meshes and errors came up


def test_file_names_that_are_not_utf8(tmp_path):
    p, f = grid_mesh(4)
    name = os.fsdecode(b"m\xe9sh.psq")  # Latin-1 bytes: a surrogate escape in Python
    path = os.path.join(str(tmp_path), name)
    psq.write(path, p, f)
    assert len(psq.read(path).faces) == len(f)
    with psq.open(path) as s:
        assert sum(len(c.faces) for c in s) == len(f)
    assert psq.info(path)["triangles"] == len(f)
    missing = os.path.join(str(tmp_path), os.fsdecode(b"n\xe9ant.ply"))
    with pytest.raises(psq.IoError) as e:
        psq.read(missing)
    assert e.value.file == missing  # the name round-trips
