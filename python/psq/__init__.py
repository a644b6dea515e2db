# SPDX-License-Identifier: Apache-2.0
"""psq: compressed streaming triangle meshes ("processing sequences") from Python.

Whole meshes as numpy arrays::

    mesh = psq.read("scan.ply")            # any format psq reads, by content
    psq.write("scan.psq", mesh.positions, mesh.faces, bits=16)
    data = psq.encode(mesh.positions, mesh.faces)   # .psq bytes
    again = psq.decode(data)

Meshes larger than memory, chunk by chunk with the streaming decoder::

    with psq.open("city.psq") as stream:
        for chunk in stream:
            chunk.positions, chunk.faces     # numpy arrays

Files: psq.convert, psq.simplify, psq.info, psq.distance (the psq command's
conversions and measures, returning what its --json prints). Many files on
Dask: psq.batch.

Errors raise psq.Error subclasses (one per stable error code) with .code,
.message, .offset (byte offset) and .line. Every call into the C++ library
releases the GIL, so threads decode, encode and convert in parallel.
"""

import os as _os
import warnings as _warnings
from typing import Any, Dict, Iterator, List, Mapping, NamedTuple, Optional, Tuple, Union

import numpy as _np

from . import _psq
from ._errors import (BadHeaderError, BadIndexError, BadSequenceError, BadValueError, ChecksumError, Error,
                      InternalError, IoError, LimitError, TruncatedError, UnknownFormatError, UnsupportedError,
                      UsageError)

__all__ = [
    "Mesh", "ListProperty", "Chunk", "StreamReader", "OPS", "FormatWarning",
    "read", "decode", "write", "encode", "open", "convert", "simplify", "info", "distance",
    "Error", "IoError", "TruncatedError", "BadHeaderError", "BadValueError", "BadIndexError", "UnsupportedError",
    "LimitError", "UnknownFormatError", "UsageError", "InternalError", "BadSequenceError", "ChecksumError",
]

__version__ = "0.1.0"

#: Names of the processing-sequence operations, indexed by Chunk.ops values
#: (paper section 3): start, add, join, fill, end.
OPS: Tuple[str, ...] = tuple(_psq.OPS)

PathLike = Union[str, "_os.PathLike[str]"]


class FormatWarning(UserWarning):
    """psq.write dropped something the output format cannot hold (a property OBJ or Draco has no place for)."""


class ListProperty(NamedTuple):
    """A list property (a PLY list, e.g. per-face texture coordinates).

    counts: uint32 array, the length of each element's list;
    values: all lists' values, concatenated (their dtype is the property's type);
    count_type: the type the file stores the counts in ("uint8", "uint16" or "uint32";
    PLY names "uchar", "ushort", "uint" are accepted).
    """

    counts: _np.ndarray
    values: _np.ndarray
    count_type: str = "uint8"

    @property
    def offsets(self) -> _np.ndarray:
        """Where each element's list starts in values (len(counts) + 1 entries)."""
        out = _np.zeros(len(self.counts) + 1, dtype=_np.int64)
        _np.cumsum(self.counts, out=out[1:])
        return out

    def __getitem__(self, i):  # type: ignore[override]
        if isinstance(i, int) and not isinstance(i, bool):
            if i < 0:
                i += len(self.counts)
            start = int(_np.sum(self.counts[:i], dtype=_np.int64))
            return self.values[start:start + int(self.counts[i])]
        return tuple.__getitem__(self, i)

    @classmethod
    def from_lists(cls, lists, dtype=None, count_type: str = "uint8") -> "ListProperty":
        """Builds one from a sequence of sequences (one list per element)."""
        counts = _np.fromiter((len(x) for x in lists), dtype=_np.uint32, count=len(lists))
        flat = [v for x in lists for v in x]
        values = _np.asarray(flat, dtype=dtype if dtype is not None else (_np.float32 if not flat else None))
        return cls(counts, values, count_type)


def _list_property(t) -> ListProperty:
    counts, values, count_type = t
    return ListProperty(counts, values, {"uchar": "uint8", "ushort": "uint16", "uint": "uint32"}.get(count_type,
                                                                                                   count_type))


def _properties(d: Mapping[str, Any]) -> Dict[str, Any]:
    return {k: (_list_property(v) if isinstance(v, tuple) else v) for k, v in d.items()}


class Mesh:
    """A triangle mesh in memory.

    positions: float32 or float64 array, N x 3 (the file's position type);
    faces: uint32 array, M x 3, indices into positions;
    vertex_properties, face_properties: dicts from property name to a 1-D
    array (one value per vertex or face, in the property's own dtype) or a
    ListProperty;
    format: the format read ("psq", "ply", "obj", "off", "stl", "drc");
    notes: what the reader interpreted (polygons split, elements skipped...).

    Arrays read by psq are handed over without copies: their .base is the
    buffer psq filled.
    """

    __slots__ = ("positions", "faces", "vertex_properties", "face_properties", "format", "notes")

    def __init__(self, positions, faces, vertex_properties=None, face_properties=None, format: str = "",
                 notes: Optional[List[str]] = None) -> None:
        self.positions = positions
        self.faces = faces
        self.vertex_properties = dict(vertex_properties or {})
        self.face_properties = dict(face_properties or {})
        self.format = format
        self.notes = list(notes or [])

    def __repr__(self) -> str:
        return (f"psq.Mesh({len(self.positions)} vertices ({self.positions.dtype}), {len(self.faces)} triangles, "
                f"vertex properties {list(self.vertex_properties)}, face properties {list(self.face_properties)})")


def _mesh(d: Dict[str, Any]) -> Mesh:
    return Mesh(d["positions"], d["faces"], _properties(d["vertex_properties"]), _properties(d["face_properties"]),
                d["format"], d["notes"])


def _path(p) -> bytes:
    """A path for the extension: the file system's bytes, so that any file name passes."""
    if isinstance(p, (str, _os.PathLike)):
        return _os.fsencode(p)
    raise UsageError(f"expected a path, not {type(p).__name__}")


def _dir(p) -> bytes:
    return b"" if p is None else _path(p)


def read(source: Union[PathLike, bytes, bytearray, memoryview]) -> Mesh:
    """Reads a whole mesh from a file (path) or from bytes.

    Any format psq reads, recognised by content: .psq, PLY (ascii or
    binary), OBJ, OFF, STL (ascii or binary), Draco. Vertex and face
    properties come back in their own dtypes. A .psq without properties
    and with float32 positions is decoded by the codec's in-memory path
    (psq/psq_memory.h, decode_mesh). The GIL is released while reading.

    Raises psq.Error subclasses: IoError, UnknownFormatError, TruncatedError,
    BadHeaderError, ChecksumError... with .offset (byte) or .line.
    """
    if isinstance(source, (bytes, bytearray, memoryview)):
        return _mesh(_psq.read_buffer(source))
    return _mesh(_psq.read_path(_path(source)))


def decode(data: Union[bytes, bytearray, memoryview]) -> Mesh:
    """Decodes a mesh from bytes (a .psq stream, or any format psq reads)."""
    if not isinstance(data, (bytes, bytearray, memoryview)):
        raise UsageError(f"decode takes bytes, not {type(data).__name__}")
    return _mesh(_psq.read_buffer(data))


_DTYPES = {_np.dtype(t) for t in (_np.int8, _np.uint8, _np.int16, _np.uint16, _np.int32, _np.uint32, _np.float32,
                                  _np.float64)}


def _column_values(name: str, values, what: str) -> _np.ndarray:
    a = _np.asarray(values)
    if a.dtype == _np.bool_:
        a = a.astype(_np.uint8)
    elif a.dtype == _np.float16:
        a = a.astype(_np.float32)
    elif a.dtype.kind in "iu" and a.dtype not in _DTYPES:
        target = _np.int32 if a.dtype.kind == "i" else _np.uint32
        info = _np.iinfo(target)
        if a.size and (a.min() < info.min or a.max() > info.max):
            raise UsageError(f"{what} property '{name}': values do not fit {_np.dtype(target).name}")
        a = a.astype(target)
    if a.dtype not in _DTYPES:
        raise UsageError(f"{what} property '{name}': dtype {a.dtype} is not one psq stores "
                         "(int8/16/32, uint8/16/32, float32, float64)")
    if a.ndim != 1:
        raise UsageError(f"{what} property '{name}' must be 1-D (one value per element), not of shape {a.shape}")
    return _np.ascontiguousarray(a)


def _columns(props: Optional[Mapping[str, Any]], what: str) -> list:
    out = []
    for name, v in (props or {}).items():
        if isinstance(v, ListProperty) or (isinstance(v, tuple) and len(v) in (2, 3)
                                           and not isinstance(v[0], (int, float))):
            lp = v if isinstance(v, ListProperty) else ListProperty(*v)
            counts = _np.ascontiguousarray(lp.counts, dtype=_np.uint32)
            out.append((str(name), _column_values(name, lp.values, what), counts, lp.count_type))
        else:
            out.append((str(name), _column_values(name, v, what), None, ""))
    return out


def _geometry(positions, faces):
    if isinstance(positions, Mesh):
        m = positions
        return m.positions, m.faces, m.vertex_properties, m.face_properties
    if faces is None:
        raise UsageError("faces are missing")
    return positions, faces, None, None


def _arrays(positions, faces):
    p = _np.asarray(positions)
    if p.dtype not in (_np.float32, _np.float64):
        p = p.astype(_np.float64)
    p = _np.ascontiguousarray(p)
    f = _np.asarray(faces)
    if f.size == 0:
        f = f.reshape(0, 3) if f.ndim != 2 else f
    if f.dtype != _np.uint32:
        if f.dtype.kind not in "iu":
            raise UsageError(f"faces must be integers, not {f.dtype}")
        if f.size and (f.min() < 0 or f.max() > 0xFFFFFFFF):
            raise BadIndexError("a face index is negative or beyond 32 bits")
        f = f.astype(_np.uint32)
    return p, _np.ascontiguousarray(f)


def _size(v) -> int:
    """A byte count: an int, or text with K, M, G or T (powers of 1024)."""
    if isinstance(v, int):
        return v
    s = str(v).strip().upper().removesuffix("IB").removesuffix("B")
    mult = {"K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}.get(s[-1:], 1)
    try:
        return int(float(s[:-1] if mult > 1 else s) * mult)
    except ValueError:
        raise UsageError(f"bad size '{v}' (e.g. 256M, 2G)") from None


def _write_options(bits, lossless, profile, chunk_bytes, zstd_level, format, ascii, overwrite, memory, tmpdir,
                   normal_bits=0, uv_bits=0):
    return dict(bits=int(bits), lossless=bool(lossless), normal_bits=int(normal_bits), uv_bits=int(uv_bits),
                profile=str(profile), chunk_bytes=_size(chunk_bytes),
                zstd_level=int(zstd_level), format=format, ascii=bool(ascii), overwrite=bool(overwrite),
                memory=_size(memory), tmpdir=None if tmpdir is None else _path(tmpdir))


def write(path: PathLike, positions, faces=None, *, bits: int = 16, lossless: bool = False,
          normal_bits: int = 0, uv_bits: int = 0,
          vertex_properties: Optional[Mapping[str, Any]] = None,
          face_properties: Optional[Mapping[str, Any]] = None, format: Optional[str] = None,
          profile: str = "auto", chunk_bytes: Union[int, str] = 1 << 20, zstd_level: int = 9,
          ascii: bool = False, overwrite: bool = True, memory: Union[int, str] = "512M",
          tmpdir: Optional[PathLike] = None) -> None:
    """Writes a mesh to a file: .psq, .ply, .obj or .drc (by `format` or the extension).

    positions: N x 3 float32 or float64 (a psq.Mesh may be passed instead of
    positions and faces); faces: M x 3 integer indices (uint32 is read in
    place; other integer types are converted). Arrays already C-contiguous
    in a dtype psq stores are read in place, without copies.
    bits: quantization bits per coordinate (.psq 1..31, .drc 1..30);
    lossless: keep positions bit-exact; normal_bits, uv_bits: quantize the
    normals (nx ny nz; octahedral, 2..16 bits) and texture coordinates (u v,
    s t; a grid of 2^-uv_bits) of a .psq, 0 (the default) keeping them
    exact; profile: .psq "compact", "fast" or
    "auto" (fast from 131072 triangles); ascii: ascii PLY. The file is
    written to a temporary file and renamed on success; overwrite=False
    refuses to replace an existing file (UsageError). What the format
    cannot hold (face properties in OBJ, lists in Draco) is dropped with a
    psq.FormatWarning naming it. The GIL is released while encoding.
    """
    positions, faces, vp, fp = _geometry(positions, faces)
    p, f = _arrays(positions, faces)
    opts = _write_options(bits, lossless, profile, chunk_bytes, zstd_level, format, ascii, overwrite, memory, tmpdir,
                          normal_bits, uv_bits)
    notes = _psq.write(_path(path), p, f,
                       _columns(vertex_properties if vertex_properties is not None else vp, "vertex"),
                       _columns(face_properties if face_properties is not None else fp, "face"), opts)
    for note in notes:
        _warnings.warn(f"{_os.fsdecode(_path(path))}: {note}", FormatWarning, stacklevel=2)


def encode(positions, faces=None, *, bits: int = 16, lossless: bool = False,
           normal_bits: int = 0, uv_bits: int = 0,
           vertex_properties: Optional[Mapping[str, Any]] = None,
           face_properties: Optional[Mapping[str, Any]] = None, profile: str = "auto",
           chunk_bytes: Union[int, str] = 1 << 20, zstd_level: int = 9, memory: Union[int, str] = "512M",
           tmpdir: Optional[PathLike] = None) -> bytes:
    """Encodes a mesh to .psq bytes; the arguments are write()'s."""
    positions, faces, vp, fp = _geometry(positions, faces)
    p, f = _arrays(positions, faces)
    opts = _write_options(bits, lossless, profile, chunk_bytes, zstd_level, "psq", False, True, memory, tmpdir,
                          normal_bits, uv_bits)
    return _psq.encode(p, f, _columns(vertex_properties if vertex_properties is not None else vp, "vertex"),
                       _columns(face_properties if face_properties is not None else fp, "face"), opts)


class Chunk:
    """A piece of a processing sequence, as psq.open yields it.

    Vertices are numbered as the sequence introduces them (its dense
    numbering: 0, 1, 2, ... across chunks); a vertex re-appearing at a
    non-manifold cut has a number of its own and `reappears` names its
    first occurrence.

    positions: the vertices this chunk introduces (float32 or float64, k x 3),
        numbered vertex_start, vertex_start + 1, ...;
    reappears: int64 per introduced vertex: the earlier vertex it re-appears, or -1;
    faces: uint32 m x 3, the chunk's triangles in the global numbering;
    ops: uint8 per triangle, an index into psq.OPS (start, add, join, fill, end);
    new_mask, final_mask, border_mask: uint8 per triangle, bit k for corner k
        (new: introduced for this triangle, i.e. its first use; final: its last
        use) or edge k (border: no other triangle shares it);
    finalized: uint32, the vertices whose last use went by in this chunk, in order;
    vertex_properties, face_properties: as Mesh's, for this chunk's elements;
    vertex_start, triangle_start: the numbers of the chunk's first vertex and triangle.
    """

    __slots__ = ("positions", "reappears", "faces", "ops", "new_mask", "final_mask", "border_mask", "finalized",
                 "vertex_properties", "face_properties", "vertex_start", "triangle_start")

    def __init__(self, d: Dict[str, Any]) -> None:
        for k in self.__slots__:
            v = d[k]
            setattr(self, k, _properties(v) if k.endswith("_properties") else v)

    @property
    def nbytes(self) -> int:
        """Bytes the chunk's arrays take."""
        total = 0
        for k in ("positions", "reappears", "faces", "ops", "new_mask", "final_mask", "border_mask", "finalized"):
            total += getattr(self, k).nbytes
        for props in (self.vertex_properties, self.face_properties):
            for v in props.values():
                total += v.counts.nbytes + v.values.nbytes if isinstance(v, ListProperty) else v.nbytes
        return total

    def __repr__(self) -> str:
        return (f"psq.Chunk(vertices {self.vertex_start}..+{len(self.positions)}, "
                f"triangles {self.triangle_start}..+{len(self.faces)}, {len(self.finalized)} finalized)")


class StreamReader:
    """A .psq read chunk by chunk (psq.open): a context manager and an iterator of Chunks.

    Memory is the decoder's (its processing boundary and one compressed
    chunk, as in C++) plus the chunk being yielded: at most
    `chunk_triangles` triangles and as many introduced vertices. The GIL is
    released while decoding.
    """

    def __init__(self, source, chunk_triangles: int = 65536) -> None:
        if chunk_triangles < 1:
            raise UsageError("chunk_triangles must be at least 1")
        self.chunk_triangles = int(chunk_triangles)
        if isinstance(source, (bytes, bytearray, memoryview)):
            self._reader = _psq.Reader(source, False)
        else:
            self._reader = _psq.Reader(_path(source), True)
        self._closed = False

    @property
    def header(self) -> Dict[str, Any]:
        """The stream's header: version, profile, lossless, bits, step, origin, position_type, counts, properties."""
        return self._reader.header()

    @property
    def stats(self) -> Dict[str, Any]:
        """Counts so far: vertices, triangles, chunks, total_bytes, max_active_vertices, max_open_edges."""
        return self._reader.stats()

    def __iter__(self) -> Iterator[Chunk]:
        return self

    def __next__(self) -> Chunk:
        if self._closed:
            raise StopIteration
        d = self._reader.next(self.chunk_triangles)
        if d is None:
            raise StopIteration
        return Chunk(d)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._reader.close()

    def __enter__(self) -> "StreamReader":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def open(source: Union[PathLike, bytes, bytearray, memoryview], chunk_triangles: int = 65536) -> StreamReader:
    """Opens a .psq (a path, or bytes) for streaming: iterate over it for Chunks.

    Use it as a context manager::

        with psq.open("big.psq", chunk_triangles=100_000) as stream:
            for chunk in stream:
                ...

    Raises UnknownFormatError for anything but a .psq (psq.read reads the others).
    """
    return StreamReader(source, chunk_triangles)


def _json(text: str) -> Dict[str, Any]:
    import json
    return json.loads(text)


def convert(src: PathLike, dst: PathLike, *, to: Optional[str] = None, bits: int = 16, lossless: bool = False,
            normal_bits: int = 10, uv_bits: int = 12, weld: Optional[str] = None, profile: str = "auto", chunk_bytes: Union[int, str] = "1M", ascii: bool = False,
            memory: Union[int, str] = "512M", tmpdir: Optional[PathLike] = None, threads: int = 1,
            overwrite: bool = True, measure_costs: bool = False, zstd_level: int = 9) -> Dict[str, Any]:
    """Converts a mesh file to another format, streaming, as `psq convert` does.

    The input format is recognised by content; the output's comes from `to`
    or dst's extension (.psq, .ply, .obj, .drc). To .psq the mesh goes
    through the processing-sequence builder (within `memory`). threads=2
    encodes on a second thread. measure_costs splits the bits into
    connectivity and geometry (slower). Returns the summary `psq convert
    --json` prints (vertices, triangles, bytes_in, bytes_out, ...). The GIL
    is released throughout. normal_bits and uv_bits quantize normals
    (octahedral) and texture coordinates (a grid of 2^-uv_bits) in a .psq,
    as `psq convert --normal-bits/--uv-bits` (0 keeps them exact; lossless
    keeps everything exact); weld="all" or "positions" merges identical
    vertices first, as `psq convert --weld`; weld="corners" merges a mesh
    split at its seams, normals and texture coordinates kept per corner,
    as `psq convert --weld=corners`.
    """
    opts = _write_options(bits, lossless, profile, chunk_bytes, zstd_level, to, ascii, overwrite, memory, tmpdir,
                          normal_bits, uv_bits)
    opts.update(threads=int(threads), measure_costs=bool(measure_costs), weld="off" if weld is None else str(weld))
    return _json(_psq.convert(_path(src), _path(dst), opts))


def simplify(src: PathLike, dst: PathLike, *, method: str = "clustering", ratio: Optional[float] = None,
             triangles: Optional[int] = None, grid: Optional[float] = None, cell: Optional[float] = None,
             cells: str = "connected", border_weight: float = 1.0, max_error: Optional[float] = None,
             buffer: Optional[int] = None, candidates: int = 8, lock_border: bool = False, seed: int = 1,
             to: Optional[str] = None, bits: Optional[int] = None, lossless: bool = False, profile: str = "auto",
             ascii: bool = False, memory: Union[int, str] = "256M", tmpdir: Optional[PathLike] = None,
             overwrite: bool = True) -> Dict[str, Any]:
    """Simplifies a mesh file out of core, as `psq simplify` does.

    method "clustering" (vertex clustering on a grid: `grid` cells along the
    longest side, default 256, or cells of edge `cell`, or a target `ratio`
    of the triangles or `triangles` count, reached by trial passes) or "qem"
    (stream edge collapse; targets: ratio, triangles, max_error relative to
    the bounding box diagonal). Output format from `to` or dst's extension.
    Returns a summary dict (input/output counts, bytes, seconds...). The GIL
    is released throughout.
    """
    opts = dict(method=method, ratio=ratio, triangles=triangles, grid=grid, cell=cell, cells=cells,
                border_weight=border_weight, max_error=max_error, buffer=buffer, candidates=candidates,
                lock_border=lock_border, seed=seed, format=to, bits=bits, lossless=lossless, profile=profile,
                ascii=ascii, overwrite=overwrite, memory=_size(memory),
                tmpdir=None if tmpdir is None else _path(tmpdir))
    return _json(_psq.simplify(_path(src), _path(dst), opts))


def info(path: PathLike, *, memory: Union[int, str] = "512M", tmpdir: Optional[PathLike] = None) -> Dict[str, Any]:
    """What a mesh file holds: the fields `psq info --json` prints.

    Counts, bounding box, border/non-manifold edges, and from its processing
    sequence: components, border loops, handles, ops, the longest boundary;
    for a .psq also its version, quantization, size and bits per vertex.
    """
    return _json(_psq.info(_path(path), _size(memory), _dir(tmpdir)))


def distance(a: PathLike, b: PathLike, *, samples: int = 0, seed: int = 1, threads: int = 0, hold: str = "auto",
             tmpdir: Optional[PathLike] = None) -> Dict[str, Any]:
    """Metro's surface distance between two mesh files: the fields `psq distance --json` prints.

    samples: per direction (0: 10 per triangle, at most 4M); hold: which mesh
    is held in memory ("auto", "a", "b", "both"); threads: 0 for one per
    processor. The numbers but 'timing' are the same for the same seed.
    """
    return _json(_psq.distance(_path(a), _path(b), int(samples), int(seed), int(threads), str(hold),
                               _dir(tmpdir)))

for _cls in (Error, IoError, TruncatedError, BadHeaderError, BadValueError, BadIndexError, UnsupportedError, LimitError,
             UnknownFormatError, UsageError, InternalError, BadSequenceError, ChecksumError):
    _cls.__module__ = "psq"
del _cls
