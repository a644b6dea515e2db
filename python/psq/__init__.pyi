# SPDX-License-Identifier: Apache-2.0
# Type stub of the psq package (the documented API; see __init__.py).
import os
from typing import Any, Dict, Iterator, List, Mapping, NamedTuple, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

from ._errors import (BadHeaderError as BadHeaderError, BadIndexError as BadIndexError,
                      BadSequenceError as BadSequenceError, BadValueError as BadValueError,
                      ChecksumError as ChecksumError, Error as Error, InternalError as InternalError,
                      IoError as IoError, LimitError as LimitError, TruncatedError as TruncatedError,
                      UnknownFormatError as UnknownFormatError, UnsupportedError as UnsupportedError,
                      UsageError as UsageError)

__version__: str
OPS: Tuple[str, ...]

PathLike = Union[str, os.PathLike[str]]
Buffer = Union[bytes, bytearray, memoryview]
Size = Union[int, str]


class FormatWarning(UserWarning): ...


class ListProperty(NamedTuple):
    counts: npt.NDArray[np.uint32]
    values: np.ndarray
    count_type: str = ...
    @property
    def offsets(self) -> npt.NDArray[np.int64]: ...
    @classmethod
    def from_lists(cls, lists: Any, dtype: Any = ..., count_type: str = ...) -> ListProperty: ...


Property = Union[np.ndarray, ListProperty]


class Mesh:
    positions: Union[npt.NDArray[np.float32], npt.NDArray[np.float64]]
    faces: npt.NDArray[np.uint32]
    vertex_properties: Dict[str, Property]
    face_properties: Dict[str, Property]
    format: str
    notes: List[str]
    def __init__(self, positions: Any, faces: Any, vertex_properties: Optional[Mapping[str, Property]] = ...,
                 face_properties: Optional[Mapping[str, Property]] = ..., format: str = ...,
                 notes: Optional[List[str]] = ...) -> None: ...


class Chunk:
    positions: Union[npt.NDArray[np.float32], npt.NDArray[np.float64]]
    reappears: npt.NDArray[np.int64]
    faces: npt.NDArray[np.uint32]
    ops: npt.NDArray[np.uint8]
    new_mask: npt.NDArray[np.uint8]
    final_mask: npt.NDArray[np.uint8]
    border_mask: npt.NDArray[np.uint8]
    finalized: npt.NDArray[np.uint32]
    vertex_properties: Dict[str, Property]
    face_properties: Dict[str, Property]
    vertex_start: int
    triangle_start: int
    @property
    def nbytes(self) -> int: ...


class StreamReader:
    chunk_triangles: int
    def __init__(self, source: Union[PathLike, Buffer], chunk_triangles: int = ...) -> None: ...
    @property
    def header(self) -> Dict[str, Any]: ...
    @property
    def stats(self) -> Dict[str, Any]: ...
    def __iter__(self) -> Iterator[Chunk]: ...
    def __next__(self) -> Chunk: ...
    def close(self) -> None: ...
    def __enter__(self) -> StreamReader: ...
    def __exit__(self, *exc: Any) -> None: ...


def read(source: Union[PathLike, Buffer]) -> Mesh: ...
def decode(data: Buffer) -> Mesh: ...
def write(path: PathLike, positions: Any, faces: Any = ..., *, bits: int = ..., lossless: bool = ...,
          normal_bits: int = ..., uv_bits: int = ...,
          vertex_properties: Optional[Mapping[str, Any]] = ..., face_properties: Optional[Mapping[str, Any]] = ...,
          format: Optional[str] = ..., profile: str = ..., chunk_bytes: Size = ..., zstd_level: int = ...,
          ascii: bool = ..., overwrite: bool = ..., memory: Size = ..., tmpdir: Optional[PathLike] = ...) -> None: ...
def encode(positions: Any, faces: Any = ..., *, bits: int = ..., lossless: bool = ...,
           normal_bits: int = ..., uv_bits: int = ...,
           vertex_properties: Optional[Mapping[str, Any]] = ..., face_properties: Optional[Mapping[str, Any]] = ...,
           profile: str = ..., chunk_bytes: Size = ..., zstd_level: int = ..., memory: Size = ...,
           tmpdir: Optional[PathLike] = ...) -> bytes: ...
def open(source: Union[PathLike, Buffer], chunk_triangles: int = ...) -> StreamReader: ...
def convert(src: PathLike, dst: PathLike, *, to: Optional[str] = ..., bits: int = ..., lossless: bool = ...,
            normal_bits: int = ..., uv_bits: int = ..., weld: Optional[str] = ...,
            profile: str = ..., chunk_bytes: Size = ..., ascii: bool = ..., memory: Size = ...,
            tmpdir: Optional[PathLike] = ..., threads: int = ..., overwrite: bool = ..., measure_costs: bool = ...,
            zstd_level: int = ...) -> Dict[str, Any]: ...
def simplify(src: PathLike, dst: PathLike, *, method: str = ..., ratio: Optional[float] = ...,
             triangles: Optional[int] = ..., grid: Optional[float] = ..., cell: Optional[float] = ...,
             cells: str = ..., border_weight: float = ..., max_error: Optional[float] = ...,
             buffer: Optional[int] = ..., candidates: int = ..., lock_border: bool = ..., seed: int = ...,
             to: Optional[str] = ..., bits: Optional[int] = ..., lossless: bool = ..., profile: str = ...,
             ascii: bool = ..., memory: Size = ..., tmpdir: Optional[PathLike] = ...,
             overwrite: bool = ...) -> Dict[str, Any]: ...
def info(path: PathLike, *, memory: Size = ..., tmpdir: Optional[PathLike] = ...) -> Dict[str, Any]: ...
def distance(a: PathLike, b: PathLike, *, samples: int = ..., seed: int = ..., threads: int = ..., hold: str = ...,
             tmpdir: Optional[PathLike] = ...) -> Dict[str, Any]: ...
